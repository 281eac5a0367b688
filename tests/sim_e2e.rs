//! End-to-end tests of `lgdm sim grasp`, driving the real binary: a short run of each scenario
//! writes `results.json` with the documented schema (attempts, rounds, summary rates with
//! Wilson intervals, per category, per failure reason), the summary and the plots; the same seed
//! twice gives the same results (wall-clock fields aside), also when the second run is recorded
//! (`--record`: an MCAP and a storyboard per round in `rounds/`); bad input (`--rounds 0`, an unknown
//! scenario, a mesh whose hull cannot be built, an object larger than the table, a foreign
//! `--out`) fails with a message naming the problem and writes nothing.
//!
//! Run in release (`cargo test --release -p lgdm-cli --test sim_e2e`): the physics is slow in a
//! debug build.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

#[path = "common/mod.rs"]
mod common;
use common::{assert_rate, check, lgdm, read_results, without_wall};

fn work_dir() -> PathBuf {
    common::work_dir("sim-e2e")
}

fn sim(out: &Path, args: &[&str]) -> Output {
    lgdm(&work_dir().join("cache"))
        .args(["sim", "grasp", "--progress", "none"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

const REASONS: [&str; 7] = [
    "no_grasp_found",
    "unreachable",
    "collision_on_approach",
    "missed",
    "slipped_during_lift",
    "slipped_during_carry",
    "dropped_outside",
];

fn check_schema(r: &Value, scenario: &str, source: &str, rounds: u64) {
    assert_eq!(r["format_version"], 1);
    assert_eq!(r["run"]["scenario"], scenario);
    assert_eq!(r["run"]["grasp_source"], source);
    assert_eq!(r["run"]["rounds"], rounds);
    let attempts = r["attempts"].as_array().unwrap();
    let s = &r["summary"];
    assert_eq!(s["attempts"].as_u64().unwrap(), attempts.len() as u64);
    assert!(!attempts.is_empty());
    for key in [
        "grasp_success_rate",
        "placement_success_rate",
        "cleared_fraction",
        "contact_only_success_rate",
    ] {
        assert_rate(&s[key], key);
    }
    let reasons = s["failure_reasons"].as_object().unwrap();
    for reason in REASONS {
        assert!(reasons.contains_key(reason), "{reason} missing: {s}");
    }
    let failed: u64 = reasons.values().map(|v| v.as_u64().unwrap()).sum();
    let per_category = s["per_category"].as_object().unwrap();
    let by_category: u64 = per_category
        .values()
        .map(|c| c["attempts"].as_u64().unwrap())
        .sum();
    assert_eq!(by_category, attempts.len() as u64);
    let mut grasped = 0;
    let mut reasons_seen = 0;
    for a in attempts {
        for key in [
            "index",
            "round",
            "object",
            "category",
            "object_pose",
            "grasp",
            "grasp_success",
            "contact_only_success",
            "placement_success",
            "reason",
            "sim_time_s",
            "wall",
        ] {
            assert!(a.get(key).is_some(), "attempt lacks {key}: {a}");
        }
        let ok = a["grasp_success"].as_bool().unwrap();
        let placed = a["placement_success"].as_bool().unwrap();
        grasped += u64::from(ok);
        // A placement needs a grasp; a failure has a reason and a success none.
        assert!(!placed || ok, "{a}");
        assert_eq!(a["reason"].is_null(), placed, "{a}");
        reasons_seen += u64::from(!a["reason"].is_null());
        if !a["grasp"].is_null() {
            let g = &a["grasp"];
            assert!(
                g["crop"]["center_px"].is_array() && g["plan"]["tcp_m"].is_array(),
                "{a}"
            );
            let opening = g["plan"]["opening_m"].as_f64().unwrap();
            assert!((0.0..=0.085 + 1e-9).contains(&opening), "{a}");
        }
        assert!(a["sim_time_s"].as_f64().unwrap() >= 0.0);
    }
    assert_eq!(reasons_seen, failed);
    assert_eq!(
        s["grasp_success_rate"]["successes"].as_u64().unwrap(),
        grasped
    );
    let rounds_list = r["rounds"].as_array().unwrap();
    assert_eq!(rounds_list.len() as u64, rounds);
    let presented: u64 = rounds_list
        .iter()
        .map(|x| x["objects"].as_array().unwrap().len() as u64)
        .sum();
    assert_eq!(s["cleared_fraction"]["trials"].as_u64().unwrap(), presented);
}

#[test]
fn isolated_analytic_writes_results_and_same_seed_gives_same_results() {
    let dir = work_dir();
    let (a, b) = (dir.join("iso-a"), dir.join("iso-b"));
    let args = [
        "--scenario",
        "isolated",
        "--grasp",
        "analytic",
        "--rounds",
        "2",
        "--seed",
        "0",
    ];
    let out = check(sim(&a, &args), "sim grasp isolated");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("grasp success") && stdout.contains("Wilson"),
        "{stdout}"
    );
    for f in [
        "results.json",
        "summary.txt",
        "success_by_category.png",
        "failure_reasons.png",
    ] {
        assert!(a.join(f).is_file(), "{f} missing");
    }
    let ra = read_results(&a);
    check_schema(&ra, "isolated", "analytic", 2);
    // Isolated rounds show one object each, and the first two categories of the library.
    let cats: Vec<&str> = ra["attempts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["category"].as_str().unwrap())
        .collect();
    assert!(
        cats.contains(&"mug") && cats.contains(&"teapot"),
        "{cats:?}"
    );

    // Again, recorded: the same results, and an MCAP and a storyboard per round.
    let mut recorded: Vec<&str> = args.to_vec();
    recorded.push("--record");
    check(sim(&b, &recorded), "sim grasp isolated --record");
    assert_eq!(without_wall(&ra), without_wall(&read_results(&b)));
    for round in ["round-0000", "round-0001"] {
        let mcap = std::fs::read(b.join("rounds").join(format!("{round}.mcap"))).unwrap();
        assert!(
            mcap.starts_with(b"\x89MCAP0\r\n") && mcap.len() > 10_000,
            "{round}"
        );
        let png = std::fs::read(b.join("rounds").join(format!("{round}.png"))).unwrap();
        assert!(png.starts_with(b"\x89PNG"), "{round}");
    }
    // A recorded run directory is replaced with --force like any other run.
    let mut forced: Vec<&str> = args.to_vec();
    forced.push("--force");
    check(sim(&b, &forced), "sim grasp --force over a recorded run");
    assert!(!b.join("rounds").exists());

    // The same directory again: refused, then replaced with --force.
    let out = sim(&a, &args);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--force"), "{err}");
    let mut forced: Vec<&str> = args.to_vec();
    forced.push("--force");
    check(sim(&a, &forced), "sim grasp --force");
}

#[test]
fn another_seed_gives_other_results() {
    let dir = work_dir();
    let args = |seed: &'static str| ["--grasp", "random", "--rounds", "2", "--seed", seed];
    check(sim(&dir.join("seed-1"), &args("1")), "seed 1");
    check(sim(&dir.join("seed-2"), &args("2")), "seed 2");
    let (a, b) = (
        read_results(&dir.join("seed-1")),
        read_results(&dir.join("seed-2")),
    );
    check_schema(&a, "isolated", "random", 2);
    assert_ne!(without_wall(&a["attempts"]), without_wall(&b["attempts"]));
}

#[test]
fn packed_pile_and_scattered_rounds_write_results() {
    let dir = work_dir();
    for scenario in ["packed", "pile", "scattered"] {
        let out = dir.join(scenario);
        check(
            sim(
                &out,
                &[
                    "--scenario",
                    scenario,
                    "--rounds",
                    "1",
                    "--seed",
                    "3",
                    "--instances",
                    "1",
                ],
            ),
            scenario,
        );
        let r = read_results(&out);
        check_schema(&r, scenario, "analytic", 1);
        assert_eq!(r["rounds"][0]["objects"].as_array().unwrap().len(), 5);
    }
}

fn assert_fails(out: Output, needles: &[&str]) {
    assert!(!out.status.success(), "unexpectedly succeeded");
    let err = String::from_utf8_lossy(&out.stderr);
    for n in needles {
        assert!(err.contains(n), "missing {n:?} in: {err}");
    }
}

/// A mesh directory with one OBJ file.
fn mesh_dir(name: &str, obj: &str) -> PathBuf {
    let dir = work_dir().join(name);
    std::fs::create_dir_all(dir.join("thing")).unwrap();
    std::fs::write(dir.join("thing").join("it.obj"), obj).unwrap();
    dir
}

#[test]
fn bad_input_is_a_clear_error_and_writes_nothing() {
    let dir = work_dir();
    let out = dir.join("bad");
    assert_fails(sim(&out, &["--rounds", "0"]), &["--rounds 0"]);
    assert!(!out.exists());
    assert_fails(
        sim(&out, &["--scenario", "heap"]),
        &["heap", "isolated, packed, pile"],
    );
    // A flat mesh: no volume, no convex hull.
    let flat = mesh_dir(
        "flat",
        "v 0 0 0\nv 0.1 0 0\nv 0.1 0.1 0\nv 0 0.1 0\nf 1 2 3\nf 1 3 4\n",
    );
    assert_fails(
        sim(&out, &["--meshes", flat.to_str().unwrap(), "--units", "m"]),
        &["it", "convex hull"],
    );
    assert!(!out.exists());
    // A 1 m cube: larger than the 0.65 m table.
    let big = mesh_dir(
        "big",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\n\
         f 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n",
    );
    assert_fails(
        sim(&out, &["--meshes", big.to_str().unwrap(), "--units", "m"]),
        &["it", "larger than the table"],
    );
    assert!(!out.exists());
    // A directory holding something else is never used.
    let foreign = dir.join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    assert_fails(sim(&foreign, &["--rounds", "1", "--force"]), &["notes.txt"]);
    assert!(foreign.join("notes.txt").is_file());
    assert_fails(
        sim(&out, &["--ae-checkpoint", "ae.pt"]),
        &["--ae-checkpoint", "only applies to --grasp network"],
    );
    assert!(!out.exists());
    #[cfg(not(feature = "ae"))]
    assert_fails(
        sim(&out, &["--grasp", "network"]),
        &["built without the `ae` feature", "--features ae"],
    );
}
