//! End-to-end tests of `lgdm sim grasp`, driving the real binary: a short run of each scenario
//! writes `results.json` with the documented schema (attempts, rounds, summary rates with their
//! Wilson intervals, per category, per failure reason), the summary and plots that show the
//! data; the same seed twice gives the same results (wall-clock fields aside), also when the
//! second run is recorded (`--record`: an MCAP and a storyboard per round in `rounds/`); on fixed
//! seeds the analytic grasps clear success floors on isolated objects and on each cluttered
//! table, and random grasps do worse than analytic ones on the same rounds; bad input
//! (`--rounds 0`, an unknown scenario, a mesh whose hull cannot be built, an object larger than
//! the table, a foreign `--out`) fails with a message naming the problem and writes nothing.
//!
//! Run in release (`cargo test --release -p lgdm-cli --test sim_e2e`): the physics is slow in a
//! debug build.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

#[path = "common/mod.rs"]
mod common;
use common::{
    assert_grasp_plots, assert_rate, assert_storyboard, check, lgdm, rate_counts, read_results,
    without_wall,
};

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

const REASONS: [&str; 10] = [
    "no_grasp_found",
    "wider_than_gripper",
    "unreachable",
    "collision_on_approach",
    "arm_collision",
    "missed",
    "slipped_during_lift",
    "slipped_during_carry",
    "dropped_outside",
    "still_moving",
];

fn check_schema(r: &Value, scenario: &str, source: &str, rounds: u64) {
    // The default gripper's stroke (the runs here leave --gripper out).
    let stroke = f64::from(lgdm_sim::robot::gripper::GripperConfig::default().stroke_m);
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
    let mut placed_seen = 0;
    let mut reasons_seen = 0;
    let mut by_reason = std::collections::BTreeMap::<String, u64>::new();
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
            assert!((0.0..=stroke + 1e-9).contains(&opening), "{a}");
        }
        // A successful grasp moved the arm: approach, close and lift take seconds.
        if ok {
            let t = a["sim_time_s"].as_f64().unwrap();
            assert!(t > 1.0, "a successful grasp took {t} s of sim time: {a}");
        }
        placed_seen += u64::from(placed);
        if let Some(reason) = a["reason"].as_str() {
            *by_reason.entry(reason.to_string()).or_default() += 1;
        }
    }
    assert_eq!(reasons_seen, failed);
    // Each reason's count is the number of attempts that failed for it.
    for (reason, n) in reasons {
        assert_eq!(
            n.as_u64().unwrap(),
            by_reason.get(reason).copied().unwrap_or(0),
            "{reason}: {s}"
        );
    }
    assert_eq!(
        s["grasp_success_rate"]["successes"].as_u64().unwrap(),
        grasped
    );
    assert_eq!(
        s["placement_success_rate"]["successes"].as_u64().unwrap(),
        placed_seen
    );
    // The categories' counts add up to the whole.
    let grasped_by_category: u64 = per_category
        .values()
        .map(|c| c["grasp_success_rate"]["successes"].as_u64().unwrap())
        .sum();
    assert_eq!(grasped_by_category, grasped, "{s}");
    for (c, cs) in per_category {
        assert_rate(&cs["grasp_success_rate"], c);
        assert_eq!(cs["grasp_success_rate"]["trials"], cs["attempts"], "{c}");
    }
    let rounds_list = r["rounds"].as_array().unwrap();
    assert_eq!(rounds_list.len() as u64, rounds);
    let presented: u64 = rounds_list
        .iter()
        .map(|x| x["objects"].as_array().unwrap().len() as u64)
        .sum();
    assert_eq!(s["cleared_fraction"]["trials"].as_u64().unwrap(), presented);
    // The rounds' attempts and placements are the run's.
    let sum = |key: &str| -> u64 { rounds_list.iter().map(|x| x[key].as_u64().unwrap()).sum() };
    assert_eq!(sum("attempts"), attempts.len() as u64);
    assert_eq!(
        sum("placed"),
        s["cleared_fraction"]["successes"].as_u64().unwrap()
    );
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
    assert_grasp_plots(&a, &ra);
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
        assert_storyboard(&b.join("rounds").join(format!("{round}.png")));
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

/// Analytic grasps on isolated objects clear a floor, and random grasps on the same rounds
/// (same seed: same objects, same poses) do worse.
///
/// Measured on this 2-core machine (release build) with
/// `lgdm sim grasp --scenario isolated --rounds 10 --seed 0 --grasp analytic|random`:
/// analytic 10/10 grasped and placed; random 6/10 grasped, placed and cleared — since the
/// planner drops grasps whose pads would close on air (issue 23) for every source, a random
/// draw that would is never tried (before: 1/30), and an object none of whose three draws can
/// close on anything ends its round as "no grasp found". The floors below leave a margin under
/// those: they guard against regressions, they are not tuned to the measurement.
#[test]
fn isolated_analytic_grasps_clear_a_floor_and_beat_random() {
    let dir = work_dir();
    let run = |source: &str| {
        let out = dir.join(format!("rates-{source}"));
        let args = ["--grasp", source, "--rounds", "10", "--seed", "0"];
        check(sim(&out, &args), source);
        let r = read_results(&out);
        check_schema(&r, "isolated", source, 10);
        assert_grasp_plots(&out, &r);
        r
    };
    let analytic = run("analytic");
    let s = &analytic["summary"];
    // Isolated rounds go through the ten categories in turn.
    assert_eq!(s["per_category"].as_object().unwrap().len(), 10, "{s}");
    let (grasped, tried, grasp_rate) = rate_counts(&s["grasp_success_rate"]);
    let (placed, _, _) = rate_counts(&s["placement_success_rate"]);
    let (cleared, objects, _) = rate_counts(&s["cleared_fraction"]);
    assert_eq!(objects, 10);
    assert!(
        grasped >= 7,
        "analytic grasp success {grasped}/{tried} is below the floor 7 (measured 10/10)"
    );
    assert!(
        placed >= 6 && cleared >= 6,
        "analytic placed {placed}, cleared {cleared}/10: below the floor 6 (measured 10)"
    );

    let random = run("random");
    let r = &random["summary"];
    let (r_grasped, r_tried, r_rate) = rate_counts(&r["grasp_success_rate"]);
    let (r_cleared, _, _) = rate_counts(&r["cleared_fraction"]);
    assert!(
        r_rate + 0.2 <= grasp_rate,
        "random grasps {r_grasped}/{r_tried} are not clearly worse than analytic ones \
         {grasped}/{tried} (measured 6/10 against 10/10)"
    );
    assert!(
        r_cleared + 2 <= cleared,
        "random cleared {r_cleared}/10, analytic {cleared}/10 (measured 6 against 10)"
    );
    // Random tries up to three grasps per object before giving up on it.
    assert!((10..=30).contains(&r_tried), "{r}");
}

/// Analytic grasps place something on each cluttered table.
///
/// Measured on this 2-core machine (release build) with
/// `lgdm sim grasp --scenario packed|pile|scattered --rounds 3 --seed 3 --instances 1`:
/// packed 8/15 objects cleared, pile 6/15, scattered 9/15. The floor, 3 of 15 on each table,
/// is half the lowest of those.
#[test]
fn packed_pile_and_scattered_rounds_place_objects() {
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
                    "3",
                    "--seed",
                    "3",
                    "--instances",
                    "1",
                ],
            ),
            scenario,
        );
        let r = read_results(&out);
        check_schema(&r, scenario, "analytic", 3);
        assert_grasp_plots(&out, &r);
        for round in r["rounds"].as_array().unwrap() {
            assert_eq!(round["objects"].as_array().unwrap().len(), 5, "{round}");
        }
        let (cleared, objects, _) = rate_counts(&r["summary"]["cleared_fraction"]);
        assert_eq!(objects, 15);
        assert!(
            cleared >= 3,
            "{scenario}: {cleared}/15 objects cleared, below the floor 3 (measured: packed 8, \
             pile 6, scattered 9)"
        );
    }
}

/// The tests' own Wilson interval (`common::wilson_interval`, which `assert_rate` checks every
/// rate against) gives the values of the shared fixture, computed with the Rust formula.
#[test]
fn the_tests_wilson_interval_matches_the_fixture() {
    let cases = common::wilson_fixture();
    assert!(cases.len() >= 10, "{cases:?}");
    for (s, n, lo, hi) in cases {
        let (a, b) = common::wilson_interval(s, n);
        assert!(
            (a - lo).abs() < 1e-12 && (b - hi).abs() < 1e-12,
            "{s}/{n}: ({a}, {b}) against the fixture's ({lo}, {hi})"
        );
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
    // grasp-data's settings are named as its options.
    let data = |args: &[&str]| {
        lgdm(&work_dir().join("cache"))
            .args(["sim", "grasp-data", "--progress", "none", "--out"])
            .arg(&out)
            .args(args)
            .output()
            .unwrap()
    };
    assert_fails(data(&["--scenes", "0"]), &["--scenes 0"]);
    assert_fails(data(&["--scenes", "5000"]), &["--scenes 5000", "at most"]);
    assert_fails(
        data(&[
            "--scenes",
            "1",
            "--analytic",
            "0",
            "--random",
            "0",
            "--rim",
            "0",
        ]),
        &["--analytic 0"],
    );
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

/// Issue 23: every run records the full config it used (`sim.toml`), `--config` of that file
/// reproduces the run, `--gripper` selects a preset, and a bad config is refused naming the
/// file and the field.
#[test]
fn a_runs_sim_toml_reproduces_it_and_bad_configs_name_the_field() {
    let base = work_dir().join("config");
    let first = base.join("first");
    check(
        sim(
            &first,
            &["--rounds", "2", "--seed", "4", "--gripper", "2f-140"],
        ),
        "sim grasp --gripper 2f-140",
    );
    let text = std::fs::read_to_string(first.join("sim.toml")).unwrap();
    assert!(text.contains("stroke_m = 0.14"), "{text}");
    // The sensor model is on by default and sim.toml records it.
    assert!(
        text.contains("[cameras.noise]") && text.contains("axial_base_m = 0.0012"),
        "{text}"
    );
    let config = base.join("sim.toml");
    std::fs::write(&config, &text).unwrap();
    let again = base.join("again");
    let config_arg = config.to_str().unwrap();
    check(
        sim(
            &again,
            &["--rounds", "2", "--seed", "4", "--config", config_arg],
        ),
        "sim grasp --config",
    );
    assert_eq!(
        without_wall(&read_results(&first)),
        without_wall(&read_results(&again)),
        "--config of a run's sim.toml plays the same run"
    );
    assert_eq!(
        std::fs::read_to_string(again.join("sim.toml")).unwrap(),
        text
    );

    for (bad, needles) in [
        (
            "[robot.gripper]\nstroke_m = -1.0\n",
            vec!["bad.toml", "gripper.stroke_m"],
        ),
        (
            "[robot.gripper]\nstroke = 0.1\n",
            vec!["bad.toml", "stroke"],
        ),
        ("[cameras\n", vec!["bad.toml"]),
        (
            "[cameras.noise]\naxial_base_m = -1.0\n",
            vec!["bad.toml", "noise", "axial_base_m"],
        ),
        (
            "[cameras.noise]\nedge_dropout = 1.5\n",
            vec!["bad.toml", "noise", "edge_dropout"],
        ),
        (
            "[shapes]\nparts = \"generator\"\nthicken_m = -0.004\n",
            vec!["bad.toml", "shapes.thicken_m"],
        ),
        (
            "[robot.arm.world_from_base]\ntranslation_m = [0.0, 2.0, 0.785]\n\
             rotation_rpy_rad = [0.0, 0.0, -1.5707963267948963]\n",
            vec!["bad.toml", "robot.arm", "cannot reach the table"],
        ),
    ] {
        let path = base.join("bad.toml");
        std::fs::write(&path, bad).unwrap();
        let out = base.join("bad-run");
        assert_fails(
            sim(&out, &["--rounds", "1", "--config", path.to_str().unwrap()]),
            &needles,
        );
        assert!(!out.exists(), "{bad}: nothing written");
    }
    // The run's own config inside --out is an input: never written over.
    let own = first.join("sim.toml");
    assert_fails(
        sim(
            &first,
            &[
                "--rounds",
                "1",
                "--force",
                "--config",
                own.to_str().unwrap(),
            ],
        ),
        &["--config", "inside --out"],
    );
    assert_eq!(std::fs::read_to_string(&own).unwrap(), text);
}

/// Ctrl-C (SIGINT) stops a run after the round it is playing: the process exits with 130 and
/// says how to resume, the run directory holds whole rounds, and `--resume` ends it as a run
/// never stopped (results without wall times). If the signal lands after the last round, the run
/// simply finished.
#[test]
fn ctrl_c_stops_after_a_round_and_resume_finishes_the_run() {
    let root = work_dir().join("ctrl-c");
    let _ = std::fs::remove_dir_all(&root);
    let (straight, stopped) = (root.join("straight"), root.join("stopped"));
    let args = ["--rounds", "8", "--seed", "2"];
    check(sim(&straight, &args), "straight");
    let child = lgdm(&work_dir().join("cache"))
        .args(["sim", "grasp", "--progress", "none"])
        .args(args)
        .arg("--out")
        .arg(&stopped)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    while !stopped.join("progress.json").is_file() && !stopped.join("results.json").is_file() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    if out.status.success() {
        // The signal came after the last round: nothing was stopped.
        assert!(stopped.join("results.json").is_file(), "{err}");
    } else {
        assert_eq!(out.status.code(), Some(130), "{err}");
        assert!(
            err.contains("stopped by Ctrl-C after") && err.contains("--resume"),
            "{err}"
        );
        assert!(!stopped.join("results.json").exists());
        let progress: Value =
            serde_json::from_slice(&std::fs::read(stopped.join("progress.json")).unwrap()).unwrap();
        assert!(
            progress["state"]["rounds_done"].as_u64().unwrap() >= 1,
            "{progress}"
        );
        let resumed = lgdm(&work_dir().join("cache"))
            .args(["sim", "grasp", "--progress", "none", "--resume"])
            .arg(&stopped)
            .output()
            .unwrap();
        check(resumed, "grasp --resume");
    }
    assert_eq!(
        without_wall(&read_results(&straight)),
        without_wall(&read_results(&stopped))
    );
}
