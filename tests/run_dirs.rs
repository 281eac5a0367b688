//! Nothing lost, nothing mixed: a command never writes over one of its own inputs, a run
//! directory belongs to one run (fresh, replaced with --force, or finished with --resume), a run
//! killed part way resumes to exactly what an uninterrupted run gives, and conflicting or
//! wrapping settings and mismatched data are refused with a message naming the problem. Each
//! test drives the real `lgdm` binary.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

#[path = "common/mod.rs"]
mod common;
use common::{check, lgdm, without_times};

fn work_dir() -> PathBuf {
    common::work_dir("run-dirs")
}

fn cache() -> PathBuf {
    work_dir().join("cache")
}

/// A tiny dataset (small preset, 4 frames per sequence), generated once per test binary.
fn tiny_dataset() -> &'static Path {
    static DATA: OnceLock<PathBuf> = OnceLock::new();
    DATA.get_or_init(|| {
        let dir = work_dir().join("tiny");
        check(
            lgdm(&cache())
                .args(["gen-dataset", "--preset", "small", "--frames", "4"])
                .args(["--seed", "3", "--progress", "none", "--out"])
                .arg(&dir)
                .output()
                .unwrap(),
            "gen-dataset",
        );
        dir
    })
}

fn train_cmd(out: &Path, extra: &[&str]) -> Command {
    let mut cmd = lgdm(&cache());
    cmd.args(["train", "--progress", "none", "--dataset"])
        .arg(tiny_dataset())
        .arg("--out")
        .arg(out)
        .args(extra);
    cmd
}

fn train(out: &Path, extra: &[&str]) -> Output {
    check(train_cmd(out, extra).output().unwrap(), "train")
}

fn refused(out: Output) -> String {
    assert!(
        !out.status.success(),
        "accepted:\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn metrics(dir: &Path) -> Value {
    serde_json::from_slice(&read(&dir.join("metrics.json"))).unwrap()
}

#[test]
fn merge_never_writes_over_one_of_its_inputs() {
    let base = work_dir().join("merge-inputs");
    let (a, b) = (base.join("A"), base.join("B"));
    train(&a, &["--scenario", "nc", "--trials", "1", "--seed", "0"]);
    train(&b, &["--scenario", "nc", "--trials", "1", "--seed", "1"]);
    let before: Vec<Vec<u8>> = [&a, &b]
        .iter()
        .flat_map(|d| {
            [
                read(&d.join("model-trial0.lgdm")),
                read(&d.join("metrics.json")),
            ]
        })
        .collect();
    for out in [&b, &a] {
        for force in [false, true] {
            let mut cmd = lgdm(&cache());
            cmd.arg("merge").arg(&a).arg(&b).arg("--out").arg(out);
            if force {
                cmd.arg("--force");
            }
            let err = refused(cmd.output().unwrap());
            assert!(
                err.contains("one of the runs being merged"),
                "{}: {err}",
                out.display()
            );
        }
    }
    let after: Vec<Vec<u8>> = [&a, &b]
        .iter()
        .flat_map(|d| {
            [
                read(&d.join("model-trial0.lgdm")),
                read(&d.join("metrics.json")),
            ]
        })
        .collect();
    assert!(before == after, "an input run changed");
    // Into a new directory it works, and B's model is B's.
    check(
        lgdm(&cache())
            .arg("merge")
            .arg(&a)
            .arg(&b)
            .arg("--out")
            .arg(base.join("AB"))
            .output()
            .unwrap(),
        "merge",
    );
    assert_eq!(
        read(&base.join("AB/model-trial1.lgdm")),
        read(&b.join("model-trial0.lgdm"))
    );
}

#[test]
fn features_never_write_into_their_dataset() {
    let data = work_dir().join("features-data");
    check(
        lgdm(&cache())
            .args(["gen-dataset", "--preset", "small", "--frames", "2"])
            .args(["--seed", "4", "--progress", "none", "--out"])
            .arg(&data)
            .output()
            .unwrap(),
        "gen-dataset",
    );
    let manifest = read(&data.join("manifest.json"));
    for out in [data.join("manifest.json"), data.join("x.npz")] {
        let err = refused(
            lgdm(&cache())
                .args(["features", "--progress", "none", "--dataset"])
                .arg(&data)
                .arg("--out")
                .arg(&out)
                .output()
                .unwrap(),
        );
        assert!(err.contains("inside the dataset"), "{err}");
    }
    assert_eq!(read(&data.join("manifest.json")), manifest);
    assert!(!data.join("x.npz").exists());
}

#[test]
fn a_run_directory_holds_one_run() {
    let base = work_dir().join("owned");
    let r = base.join("R");
    train(&r, &["--scenario", "ni", "--trials", "3", "--seed", "0"]);
    let old = metrics(&r);
    // Another run into R is refused and R is untouched.
    let err = refused(
        train_cmd(&r, &["--scenario", "nc", "--trials", "2"])
            .output()
            .unwrap(),
    );
    assert!(
        err.contains("holds another run") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(metrics(&r), old);
    // --force replaces it whole: no model of the old third trial is left behind.
    train(&r, &["--scenario", "nc", "--trials", "2", "--force"]);
    assert_eq!(metrics(&r)["scenario"], "nc");
    assert!(
        !r.join("model-trial2.lgdm").exists(),
        "a stale model survived"
    );
    // A directory with other files is never cleared, even with --force.
    let other = base.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let err = refused(
        train_cmd(&other, &["--scenario", "ni", "--force"])
            .output()
            .unwrap(),
    );
    assert!(err.contains("notes.txt"), "{err}");
    assert_eq!(read(&other.join("notes.txt")), b"mine");
}

#[test]
fn two_trains_into_one_directory_do_not_mix() {
    let out = work_dir().join("concurrent");
    let spawn = |seed: &str| {
        train_cmd(
            &out,
            &[
                "--scenario",
                "nic",
                "--trials",
                "2",
                "--jobs",
                "1",
                "--seed",
                seed,
            ],
        )
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
    };
    let (a, b) = (spawn("0"), spawn("7"));
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let ok = [&a, &b].iter().filter(|o| o.status.success()).count();
    assert_eq!(
        ok, 1,
        "exactly one of two concurrent runs may own the directory"
    );
    let loser = if a.status.success() { &b } else { &a };
    let err = String::from_utf8_lossy(&loser.stderr);
    assert!(
        err.contains("another lgdm process") || err.contains("holds another run"),
        "{err}"
    );
    let m = metrics(&out);
    let seed = m["seed"].as_u64().unwrap();
    assert_eq!(m["trials"].as_array().unwrap().len(), 2);
    let config = String::from_utf8(read(&out.join("config.toml"))).unwrap();
    assert!(config.contains(&format!("seed = {seed}")), "{config}");
}

/// The trial records of a run directory that are complete (record and model): what `--resume`
/// counts as done.
fn recorded_trials(dir: &Path, trials: usize) -> usize {
    (0..trials)
        .filter(|t| {
            dir.join(format!("trials/trial-{t}.json")).is_file()
                && dir.join(format!("model-trial{t}.lgdm")).is_file()
        })
        .count()
}

/// Resumes `dir` and checks that it ends as the straight run did: the resume reports the
/// `recorded` trials it found, and the metrics (timing aside) and every model are the straight
/// run's.
fn resume_matches(dir: &Path, straight: &Path, recorded: usize) {
    // Experiment flags cannot change a resumed run.
    let err = refused(
        lgdm(&cache())
            .args(["train", "--progress", "none", "--seed", "9", "--resume"])
            .arg(dir)
            .output()
            .unwrap(),
    );
    assert!(err.contains("--seed"), "{err}");
    let out = check(
        lgdm(&cache())
            .args(["train", "--progress", "bar", "--resume"])
            .arg(dir)
            .output()
            .unwrap(),
        "resume",
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("{recorded} of 2 trial(s) recorded")),
        "{}: {stderr}",
        dir.display()
    );
    assert_eq!(
        without_times(&metrics(dir)),
        without_times(&metrics(straight))
    );
    for t in ["model-trial0.lgdm", "model-trial1.lgdm"] {
        assert!(
            read(&dir.join(t)) == read(&straight.join(t)),
            "{}: {t} differs from the straight run's",
            dir.display()
        );
    }
}

/// A run stopped after its first trial — what a kill leaves: `config.toml`, the first trial's
/// model and record, no `metrics.json` — is not mistaken for a finished run and resumes to
/// exactly what an uninterrupted run gives. Then a real run is killed (SIGKILL) as soon as its
/// first trial is recorded; where the kill lands in the rest of the run (the second trial, its
/// files, `metrics.json`, or after the end) is up to the scheduler, and every assertion made
/// about it holds wherever it lands. Nothing here depends on timing.
#[test]
fn a_killed_run_resumes_to_what_a_straight_run_gives() {
    let base = work_dir().join("resume");
    let args = [
        "--scenario",
        "nic",
        "--trials",
        "2",
        "--jobs",
        "1",
        "--seed",
        "2",
    ];
    let straight = base.join("straight");
    train(&straight, &args);

    // The state a kill after the first trial leaves, made from the straight run's files.
    let stopped = base.join("stopped");
    std::fs::create_dir_all(stopped.join("trials")).unwrap();
    for f in ["config.toml", "model-trial0.lgdm", "trials/trial-0.json"] {
        std::fs::copy(straight.join(f), stopped.join(f)).unwrap();
    }
    let err = refused(
        lgdm(&cache())
            .arg("merge")
            .arg(&stopped)
            .arg("--out")
            .arg(base.join("m-stopped"))
            .output()
            .unwrap(),
    );
    assert!(err.contains("--resume"), "{err}");
    resume_matches(&stopped, &straight, 1);

    // A real kill, once the first trial's record exists.
    let killed = base.join("killed");
    let mut child = train_cmd(&killed, &args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let record = killed.join("trials/trial-0.json");
    loop {
        if record.exists() {
            break;
        }
        if let Some(status) = child.try_wait().unwrap() {
            // Ended between two looks: only by finishing, and then trial 0 is recorded.
            assert!(
                status.success() && record.exists(),
                "the run ended ({status}) without recording trial 0"
            );
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL (no effect if it has already ended)
    child.wait().unwrap();
    let recorded = recorded_trials(&killed, 2);
    let finished = killed.join("metrics.json").is_file();
    assert!(recorded >= 1, "trial 0's record without its model");
    assert!(
        !finished || recorded == 2,
        "metrics.json before every trial was recorded"
    );
    // An unfinished run is not mistaken for a finished one: merge takes only a finished run.
    let merge = lgdm(&cache())
        .arg("merge")
        .arg(&killed)
        .arg("--out")
        .arg(base.join("m-killed"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&merge.stderr);
    assert_eq!(
        merge.status.success(),
        finished,
        "merge of the killed run: {err}"
    );
    if !finished {
        assert!(err.contains("--resume"), "{err}");
    }
    println!("killed with {recorded} of 2 trials recorded, finished: {finished}");
    resume_matches(&killed, &straight, recorded);
}

#[test]
fn conflicting_and_wrapping_settings_are_refused() {
    let base = work_dir().join("flags");
    for (extra, expect) in [
        (vec!["--replay", "--no-replay"], "--no-replay"),
        (
            vec!["--seed", "18446744073709551615", "--trials", "2"],
            "overflow",
        ),
    ] {
        let out = base.join(extra.join(""));
        let mut args = vec!["--scenario", "ni"];
        args.extend(extra.iter().copied());
        let err = refused(train_cmd(&out, &args).output().unwrap());
        assert!(err.contains(expect), "{extra:?}: {err}");
        assert!(!out.join("metrics.json").exists());
    }
}

#[test]
fn a_runs_config_is_used_whole_and_its_typos_are_named() {
    let base = work_dir().join("config");
    let first = base.join("first");
    train(
        &first,
        &[
            "--scenario",
            "nc",
            "--trials",
            "1",
            "--seed",
            "4",
            "--no-replay",
            "--epochs",
            "2",
        ],
    );
    // Passed back, it repeats the run exactly (scenario, seed, replay, epochs, dataset).
    let again = base.join("again");
    check(
        lgdm(&cache())
            .args(["train", "--progress", "none", "--config"])
            .arg(first.join("config.toml"))
            .arg("--out")
            .arg(&again)
            .output()
            .unwrap(),
        "train --config run config",
    );
    let (m1, m2) = (metrics(&first), metrics(&again));
    assert_eq!(
        (m2["seed"].as_u64(), m2["replay"].as_bool()),
        (Some(4), Some(false))
    );
    assert_eq!(m2["epochs"].as_u64(), Some(2));
    assert_eq!(without_times(&m1)["trials"], without_times(&m2)["trials"]);
    // A typo names the key it is in.
    let typo = base.join("typo.toml");
    let text = String::from_utf8(read(&first.join("config.toml"))).unwrap();
    std::fs::write(
        &typo,
        text.replace("activation_threshold", "activaton_threshold"),
    )
    .unwrap();
    assert_ne!(
        read(&typo),
        read(&first.join("config.toml")),
        "no such key to misspell"
    );
    let err = refused(
        lgdm(&cache())
            .args(["train", "--progress", "none", "--config"])
            .arg(&typo)
            .arg("--out")
            .arg(base.join("typo-run"))
            .output()
            .unwrap(),
    );
    assert!(err.contains("activaton_threshold"), "{err}");
}

/// Writes an OBJ box of the given extents (metres).
fn write_box(path: &Path, [x, y, z]: [f32; 3]) {
    let mut s = String::new();
    for i in 0..8 {
        let (a, b, c) = (i & 1, (i >> 1) & 1, (i >> 2) & 1);
        s += &format!("v {} {} {}\n", a as f32 * x, b as f32 * y, c as f32 * z);
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s += &format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, s).unwrap();
}

#[test]
fn eval_refuses_a_model_of_other_categories() {
    let base = work_dir().join("eval-labels");
    let run = base.join("run");
    train(
        &run,
        &["--scenario", "batch", "--trials", "1", "--epochs", "1"],
    );
    let meshes = base.join("meshes");
    for (cat, size) in [
        ("crate", [0.30, 0.20, 0.15]),
        ("brick", [0.22, 0.10, 0.06]),
        ("tower", [0.08, 0.08, 0.35]),
    ] {
        write_box(&meshes.join(cat).join(format!("{cat}_a.obj")), size);
    }
    let other = base.join("other-data");
    check(
        lgdm(&cache())
            .args([
                "gen-dataset",
                "--preset",
                "small",
                "--frames",
                "2",
                "--grasp-images",
                "0",
            ])
            .args(["--progress", "none", "--meshes"])
            .arg(&meshes)
            .arg("--out")
            .arg(&other)
            .output()
            .unwrap(),
        "gen-dataset --meshes",
    );
    let eval = |extra: &[&str]| {
        lgdm(&cache())
            .args(["eval", "--progress", "none", "--model"])
            .arg(run.join("model-trial0.lgdm"))
            .arg("--dataset")
            .arg(&other)
            .arg("--out")
            .arg(base.join("eval"))
            .args(extra)
            .output()
            .unwrap()
    };
    let err = refused(eval(&[]));
    assert!(err.contains("categories") && err.contains("crate"), "{err}");
    assert!(!base.join("eval/eval.json").exists());
    check(eval(&["--allow-other-labels"]), "eval --allow-other-labels");
    // And --out may not be the model itself.
    let err = refused(
        lgdm(&cache())
            .args(["eval", "--progress", "none", "--model"])
            .arg(run.join("model-trial0.lgdm"))
            .arg("--dataset")
            .arg(tiny_dataset())
            .arg("--out")
            .arg(run.join("model-trial0.lgdm"))
            .output()
            .unwrap(),
    );
    assert!(err.contains("over the model"), "{err}");
}

#[test]
fn a_killed_first_use_generation_leaves_nothing_that_stays() {
    use lgdm_pointcloud::DirLock;
    let cache = work_dir().join("stale-cache");
    let datasets = cache.join("datasets");
    // What a killed generation left behind (no live process holds its lock).
    let stale = datasets.join(".tmp-4000000-small-seed0-v0.1.0");
    std::fs::create_dir_all(stale.join("collections")).unwrap();
    std::fs::write(stale.join("collections/c00_clean.mcap"), vec![0u8; 4096]).unwrap();
    // A generation that is still running (its lock is held) is left alone.
    let live = datasets.join(".tmp-4000001-small-seed0-v0.1.0");
    let lock = DirLock::try_acquire(&live).unwrap().expect("free");
    check(
        lgdm(&cache)
            .args([
                "train",
                "--scenario",
                "nc",
                "--trials",
                "1",
                "--progress",
                "none",
            ])
            .arg("--out")
            .arg(work_dir().join("stale-run"))
            .output()
            .unwrap(),
        "train on the embedded dataset",
    );
    assert!(
        !stale.exists(),
        "the stale temporary dataset is still there"
    );
    assert!(
        live.exists(),
        "a running generation's directory was removed"
    );
    drop(lock);
}

/// A generation into a directory another process is writing is refused and writes nothing; two
/// generations started together never mix. The refusal is checked deterministically against a
/// lock this test holds; for the two real processes every assertion holds however the
/// scheduler overlaps them.
#[test]
fn two_generations_into_one_directory_do_not_mix() {
    let gen_cmd = |out: &Path, seed: &str| {
        let mut cmd = lgdm(&cache());
        cmd.args([
            "gen-dataset",
            "--preset",
            "small",
            "--frames",
            "3",
            "--seed",
            seed,
        ])
        .args(["--progress", "none", "--out"])
        .arg(out);
        cmd
    };
    // While another writer holds the directory's lock: refused, nothing written.
    let held = work_dir().join("gen-held");
    let lock = lgdm_pointcloud::DirLock::try_acquire(&held)
        .unwrap()
        .expect("free");
    let err = refused(gen_cmd(&held, "1").output().unwrap());
    assert!(err.contains("another lgdm process"), "{err}");
    let left: Vec<String> = std::fs::read_dir(&held)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        left,
        [lgdm_pointcloud::LOCK_FILE],
        "a refused generation wrote"
    );
    drop(lock);

    // Two real generations at once.
    let out = work_dir().join("gen-twice");
    let spawn = |seed: &str| {
        gen_cmd(&out, seed)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn("1"), spawn("2"));
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let manifest: Value = serde_json::from_slice(&read(&out.join("manifest.json"))).unwrap();
    let seed = manifest["seed"].as_u64().unwrap();
    match (a.status.success(), b.status.success()) {
        (true, true) => {
            // They did not overlap: the second replaced the first's whole dataset.
            assert!(seed == 1 || seed == 2, "seed {seed}");
        }
        (a_ok, b_ok) => {
            assert!(a_ok || b_ok, "both generations failed");
            let loser = if a_ok { &b } else { &a };
            let err = String::from_utf8_lossy(&loser.stderr);
            assert!(err.contains("another lgdm process"), "{err}");
            assert_eq!(seed, if a_ok { 1 } else { 2 }, "the loser's dataset");
        }
    }
    assert!(!out.join(lgdm_pointcloud::LOCK_FILE).exists());
}

#[test]
fn a_killed_generation_leaves_nothing_a_rerun_trips_on() {
    let out = work_dir().join("gen-killed");
    // What a generation killed part way leaves: its lock file (no longer held), a finished
    // collection, a temporary file, no manifest.
    std::fs::create_dir_all(out.join("collections")).unwrap();
    std::fs::write(out.join(lgdm_pointcloud::LOCK_FILE), b"").unwrap();
    std::fs::write(out.join("collections/c00_clean.mcap"), vec![0u8; 64]).unwrap();
    let temp = out.join("collections/.c01_translation.mcap.a1b2c3.tmp");
    std::fs::write(&temp, vec![0u8; 64]).unwrap();
    check(
        lgdm(&cache())
            .args([
                "gen-dataset",
                "--preset",
                "small",
                "--frames",
                "2",
                "--seed",
                "5",
            ])
            .args(["--progress", "none", "--out"])
            .arg(&out)
            .output()
            .unwrap(),
        "gen-dataset over an interrupted generation",
    );
    assert!(out.join("manifest.json").is_file());
    assert!(
        !temp.exists(),
        "the killed run's temporary file is still there"
    );
    assert!(!out.join(lgdm_pointcloud::LOCK_FILE).exists());
    // A directory of other files is still refused.
    let other = work_dir().join("gen-other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let err = refused(
        lgdm(&cache())
            .args(["gen-dataset", "--preset", "small", "--frames", "2"])
            .args(["--progress", "none", "--out"])
            .arg(&other)
            .output()
            .unwrap(),
    );
    assert!(err.contains("not empty"), "{err}");
}
