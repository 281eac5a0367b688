//! A closed pipe or a refused directory costs nothing. A command whose stdout reader has gone
//! (`lgdm … | head`) ends quietly — exit 0 or killed by SIGPIPE, never a panic (101) — with its
//! files complete; a closed stderr (progress, notes, log lines, the final error) never panics;
//! and a command that refuses its output directory leaves it exactly as it was found: no
//! `.lgdm.lock`, no file created or removed, no new directory. Each test drives the real `lgdm`
//! binary; `LGDM_TEST_BIN` points them at another build (to see them fail on an older one).

use serde_json::Value;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

#[path = "common/mod.rs"]
mod common;

use lgdm_pointcloud::LOCK_FILE;

fn work_dir() -> PathBuf {
    common::work_dir("pipes-locks")
}

/// The binary under test (`$LGDM_TEST_BIN`, or this build's), with its cache in the work dir.
fn lgdm() -> Command {
    let bin = std::env::var_os("LGDM_TEST_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_lgdm")));
    let mut cmd = Command::new(bin);
    cmd.env("LGDM_CACHE_DIR", work_dir().join("cache"))
        .env_remove("LGDM_LOG")
        .stdin(Stdio::null());
    cmd
}

/// A tiny dataset (small preset, 2 frames per sequence), generated once per test binary.
fn tiny_dataset() -> &'static Path {
    static DATA: OnceLock<PathBuf> = OnceLock::new();
    DATA.get_or_init(|| {
        let dir = work_dir().join("tiny");
        common::check(
            lgdm()
                .args(["gen-dataset", "--preset", "small", "--frames", "2"])
                .args(["--grasp-images", "0", "--seed", "5", "--progress", "none"])
                .arg("--out")
                .arg(&dir)
                .output()
                .unwrap(),
            "gen-dataset",
        );
        dir
    })
}

/// `lgdm train --scenario ni` into `out` with the `extra` flags; unless they say otherwise, one
/// trial on the tiny dataset without progress.
fn train_cmd(out: &Path, extra: &[&str]) -> Command {
    let mut cmd = lgdm();
    cmd.args(["train", "--scenario", "ni"])
        .args(extra)
        .arg("--out")
        .arg(out);
    for (flag, value) in [("--trials", "1"), ("--progress", "none")] {
        if !extra.contains(&flag) {
            cmd.args([flag, value]);
        }
    }
    if !extra.contains(&"--dataset") {
        cmd.arg("--dataset").arg(tiny_dataset());
    }
    cmd
}

/// A finished one-trial run, trained once per test binary.
fn finished_run() -> &'static Path {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = work_dir().join("finished-run");
        common::check(train_cmd(&dir, &[]).output().unwrap(), "train");
        dir
    })
}

/// The write end of a pipe whose read end is already closed: every write to it fails with
/// EPIPE, deterministically.
fn closed_pipe() -> Stdio {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    writer.into()
}

/// Runs `cmd` with stdout on a closed pipe (stderr captured).
fn with_closed_stdout(cmd: &mut Command) -> Output {
    cmd.stdout(closed_pipe()).output().unwrap()
}

/// The command ended as a closed pipe should end it: exit 0 or killed by SIGPIPE; never the
/// panic exit 101, and no panic message.
fn assert_ended_quietly(out: &Output, what: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(0) || out.status.signal() == Some(13),
        "{what}: ended with {} on a closed pipe:\n{stderr}",
        out.status
    );
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A training run directory is complete: its files, metrics of `trials` trials, a summary.
fn assert_run_complete(dir: &Path, trials: usize) {
    let metrics = read_json(&dir.join("metrics.json"));
    assert_eq!(metrics["trials"].as_array().unwrap().len(), trials);
    for file in ["config.toml", "summary.txt", "accuracy.png"] {
        assert!(dir.join(file).is_file(), "{}: no {file}", dir.display());
    }
    for t in 0..trials {
        assert!(dir.join(format!("model-trial{t}.lgdm")).is_file());
    }
    let summary = std::fs::read_to_string(dir.join("summary.txt")).unwrap();
    assert!(summary.contains("category accuracy (G-SM)"), "{summary}");
}

#[test]
fn info_ends_quietly_when_stdout_is_closed() {
    let out = with_closed_stdout(lgdm().arg("info"));
    assert_ended_quietly(&out, "info");
}

#[test]
fn train_ends_quietly_when_stdout_is_closed_with_its_run_complete() {
    let dir = work_dir().join("train-closed-stdout");
    let out = with_closed_stdout(&mut train_cmd(&dir, &[]));
    assert_ended_quietly(&out, "train");
    assert_run_complete(&dir, 1);
}

#[test]
fn eval_merge_gen_dataset_and_features_end_quietly_when_stdout_is_closed() {
    let run = finished_run();
    let base = work_dir().join("closed-stdout");
    let eval = base.join("eval");
    let out = with_closed_stdout(
        lgdm()
            .args(["eval", "--progress", "none", "--model"])
            .arg(run.join("model-trial0.lgdm"))
            .arg("--dataset")
            .arg(tiny_dataset())
            .arg("--out")
            .arg(&eval),
    );
    assert_ended_quietly(&out, "eval");
    assert!(read_json(&eval.join("eval.json"))["n"].as_u64().unwrap() > 0);
    assert!(eval.join("confusion.csv").is_file() && eval.join("confusion.png").is_file());

    let merged = base.join("merged");
    let out = with_closed_stdout(lgdm().arg("merge").arg(run).arg("--out").arg(&merged));
    assert_ended_quietly(&out, "merge");
    assert_run_complete(&merged, 1);

    let data = base.join("data");
    let out = with_closed_stdout(
        lgdm()
            .args(["gen-dataset", "--preset", "small", "--frames", "1"])
            .args(["--grasp-images", "0", "--progress", "none", "--out"])
            .arg(&data),
    );
    assert_ended_quietly(&out, "gen-dataset");
    let manifest = read_json(&data.join("manifest.json"));
    assert_eq!(manifest["collections"].as_array().unwrap().len(), 15);
    assert!(!data.join(LOCK_FILE).exists());

    let npz = base.join("features.npz");
    let out = with_closed_stdout(
        lgdm()
            .args(["features", "--progress", "none", "--dataset"])
            .arg(tiny_dataset())
            .arg("--out")
            .arg(&npz),
    );
    assert_ended_quietly(&out, "features");
    assert!(std::fs::metadata(&npz).unwrap().len() > 0);
}

#[test]
fn sim_grasp_ends_quietly_when_stdout_is_closed_with_its_results_complete() {
    let dir = work_dir().join("sim-closed-stdout");
    let out = with_closed_stdout(
        lgdm()
            .args([
                "sim",
                "grasp",
                "--rounds",
                "1",
                "--progress",
                "none",
                "--out",
            ])
            .arg(&dir),
    );
    assert_ended_quietly(&out, "sim grasp");
    let results = read_json(&dir.join("results.json"));
    assert_eq!(results["run"]["rounds"], 1);
    assert!(!results["attempts"].as_array().unwrap().is_empty());
    for file in [
        "summary.txt",
        "success_by_category.png",
        "failure_reasons.png",
    ] {
        assert!(dir.join(file).is_file(), "no {file}");
    }
}

/// Progress (a bar's notes, JSON lines), log lines (`LGDM_LOG=debug`) and the final error go to
/// stderr; with it closed, a run still finishes and a refusal still exits 1.
#[test]
fn a_closed_stderr_never_panics() {
    let base = work_dir().join("closed-stderr");
    for (progress, log) in [("bar", None), ("jsonl", None), ("none", Some("debug"))] {
        let dir = base.join(format!("{progress}-{}", log.unwrap_or("warn")));
        let mut cmd = train_cmd(&dir, &["--progress", progress]);
        if let Some(level) = log {
            cmd.env("LGDM_LOG", level);
        }
        let out = cmd.stderr(closed_pipe()).output().unwrap();
        let what = format!("train --progress {progress}, LGDM_LOG {log:?}");
        assert!(out.status.success(), "{what}: {}", out.status);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(stdout.contains("run directory:"), "{what}: {stdout}");
        assert_run_complete(&dir, 1);
    }
    let refused = base.join("refused");
    let out = train_cmd(&refused, &["--trials", "0"])
        .stderr(closed_pipe())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "a refusal: {}", out.status);
}

/// Everything under a directory, sorted: relative path and, for a file, its bytes.
type Listing = Vec<(String, Option<Vec<u8>>)>;

/// The [`Listing`] of `dir`, `None` when it does not exist.
fn listing(dir: &Path) -> Option<Listing> {
    fn walk(root: &Path, dir: &Path, out: &mut Listing) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.strip_prefix(root).unwrap().display().to_string();
            if path.is_dir() {
                out.push((name, None));
                walk(root, &path, out);
            } else {
                out.push((name, Some(std::fs::read(&path).unwrap())));
            }
        }
    }
    if !dir.exists() {
        return None;
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    Some(out)
}

/// Runs `cmd`, which must refuse (exit 1), and checks that `dir` is exactly as it was.
fn assert_refused_as_found(mut cmd: Command, dir: &Path, what: &str) {
    let before = listing(dir);
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{what}: not refused:\n{stderr}");
    let after = listing(dir);
    let names = |l: &Option<Listing>| {
        l.as_ref()
            .map(|l| l.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>())
    };
    assert!(
        before == after,
        "{what} ({stderr}): {} was {:?}, is {:?}",
        dir.display(),
        names(&before),
        names(&after)
    );
}

/// Runs `cmd`, which must refuse (exit 1) an `--out /`, and checks that `/` holds the same
/// entries as before (its top level only) and no lock file. One at a time: a refusal may put a
/// lock file in `/` for a moment (as root) before it removes it.
fn assert_root_untouched(mut cmd: Command, what: &str) {
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let names = || {
        let mut names: Vec<String> = std::fs::read_dir("/")
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let before = names();
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{what}: not refused:\n{stderr}");
    assert_eq!(names(), before, "{what}: / changed ({stderr})");
}

/// A directory holding someone else's file.
fn foreign_dir(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    dir.to_path_buf()
}

/// A copy of the finished run's files (without its lock file) at `dir`.
fn copy_of_run(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir.join("trials")).unwrap();
    for entry in std::fs::read_dir(finished_run()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap();
        if path.is_file() && name != LOCK_FILE {
            std::fs::copy(&path, dir.join(name)).unwrap();
        }
    }
    let record = "trials/trial-0.json";
    std::fs::copy(finished_run().join(record), dir.join(record)).unwrap();
    dir.to_path_buf()
}

#[test]
fn refused_training_runs_leave_their_directory_as_found() {
    let base = work_dir().join("refused-train");
    let new = base.join("new");
    let empty = base.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let foreign = foreign_dir(&base.join("foreign"));
    let previous = copy_of_run(&base.join("previous"));

    for dir in [&new, &empty] {
        let cmd = train_cmd(dir, &["--trials", "0"]);
        assert_refused_as_found(cmd, dir, "train --trials 0");
    }
    let missing = base.join("no-such-dataset");
    let cmd = train_cmd(&new, &["--dataset", missing.to_str().unwrap()]);
    assert_refused_as_found(cmd, &new, "train of a missing dataset");
    let cmd = train_cmd(&foreign, &["--force"]);
    assert_refused_as_found(cmd, &foreign, "train --force into a foreign directory");
    assert_root_untouched(
        train_cmd(Path::new("/"), &["--force"]),
        "train --out / --force",
    );
    // --force removes an old run only for a run that starts.
    let cmd = train_cmd(&previous, &["--force", "--trials", "0"]);
    assert_refused_as_found(cmd, &previous, "train --force --trials 0");
}

#[test]
fn refused_resumes_leave_their_directory_as_found() {
    let base = work_dir().join("refused-resume");
    let foreign = foreign_dir(&base.join("foreign"));
    let mut cmd = lgdm();
    cmd.args(["train", "--progress", "none", "--resume"])
        .arg(&foreign);
    assert_refused_as_found(cmd, &foreign, "train --resume of a non-run");
    // Another tool's config.toml.
    let other = foreign_dir(&base.join("other-config"));
    std::fs::write(other.join("config.toml"), "[build]\njobs = 2\n").unwrap();
    let mut cmd = lgdm();
    cmd.args(["train", "--progress", "none", "--resume"])
        .arg(&other);
    assert_refused_as_found(cmd, &other, "train --resume of another tool's config");
    // A stopped run whose dataset has gone.
    let stopped = base.join("stopped");
    std::fs::create_dir_all(&stopped).unwrap();
    let config = std::fs::read_to_string(finished_run().join("config.toml")).unwrap();
    let dataset = tiny_dataset().display().to_string();
    assert!(config.contains(&dataset), "{config}");
    let moved = config.replace(&dataset, &base.join("gone").display().to_string());
    std::fs::write(stopped.join("config.toml"), moved).unwrap();
    let mut cmd = lgdm();
    cmd.args(["train", "--progress", "none", "--resume"])
        .arg(&stopped);
    assert_refused_as_found(cmd, &stopped, "train --resume without its dataset");
}

#[test]
fn refused_merges_evals_generations_and_sim_runs_leave_their_directory_as_found() {
    let base = work_dir().join("refused-other");
    let run = finished_run();
    let new = base.join("new");
    let foreign = foreign_dir(&base.join("foreign"));

    for force in [false, true] {
        let mut cmd = lgdm();
        cmd.arg("merge").arg(run).arg("--out").arg(&foreign);
        if force {
            cmd.arg("--force");
        }
        assert_refused_as_found(cmd, &foreign, "merge into a foreign directory");
    }
    let mut cmd = lgdm();
    cmd.arg("merge").arg(&foreign).arg("--out").arg(&new);
    assert_refused_as_found(cmd, &new, "merge of a non-run");

    let mut cmd = lgdm();
    cmd.args(["eval", "--progress", "none", "--model"])
        .arg(run.join("model-trial0.lgdm"))
        .arg("--dataset")
        .arg(base.join("no-such-dataset"))
        .arg("--out")
        .arg(&new);
    assert_refused_as_found(cmd, &new, "eval of a missing dataset");

    let mut cmd = lgdm();
    cmd.args(["gen-dataset", "--preset", "small", "--frames", "1"])
        .args(["--grasp-images", "0", "--progress", "none", "--out"])
        .arg(&foreign);
    assert_refused_as_found(cmd, &foreign, "gen-dataset into a foreign directory");
    let mut cmd = lgdm();
    cmd.args(["gen-dataset", "--preset", "small", "--frames", "0"])
        .args(["--progress", "none", "--out"])
        .arg(&new);
    assert_refused_as_found(cmd, &new, "gen-dataset --frames 0");

    let mut cmd = lgdm();
    cmd.args([
        "sim",
        "grasp",
        "--rounds",
        "0",
        "--progress",
        "none",
        "--out",
    ])
    .arg(&new);
    assert_refused_as_found(cmd, &new, "sim grasp --rounds 0");
    for dir in [foreign.as_path(), Path::new("/")] {
        let mut cmd = lgdm();
        cmd.args(["sim", "grasp", "--rounds", "1", "--progress", "none"])
            .args(["--force", "--out"])
            .arg(dir);
        if dir == Path::new("/") {
            assert_root_untouched(cmd, "sim grasp --out / --force");
        } else {
            assert_refused_as_found(cmd, dir, "sim grasp --force into a foreign directory");
        }
    }
}

/// `lgdm eval` of the finished run's model into `out` (`None`: its default, `eval/` beside the
/// model).
fn eval_cmd(model: &Path, out: Option<&Path>) -> Command {
    let mut cmd = lgdm();
    cmd.args(["eval", "--progress", "none", "--model"])
        .arg(model)
        .arg("--dataset")
        .arg(tiny_dataset());
    if let Some(out) = out {
        cmd.arg("--out").arg(out);
    }
    cmd
}

/// Issue 22: `eval --out` wrote its three files into any directory (a foreign one, a training
/// run, whose `train --force` then refused it for "holding eval.json"), while the `eval/`
/// folder beside a model was deleted by `train --force` whatever it held. Now eval writes only
/// into a directory of evaluations, and `train --force` replaces a run's `eval/` only when it
/// holds nothing but an evaluation.
#[test]
fn eval_writes_only_evaluations_and_force_replaces_them_only() {
    let base = work_dir().join("eval-dirs");
    let foreign = foreign_dir(&base.join("foreign"));
    let run = copy_of_run(&base.join("run"));
    let model = run.join("model-trial0.lgdm");

    let cmd = eval_cmd(&model, Some(&foreign));
    assert_refused_as_found(cmd, &foreign, "eval --out into a foreign directory");
    let other = copy_of_run(&base.join("other-run"));
    let cmd = eval_cmd(&model, Some(&other));
    assert_refused_as_found(cmd, &other, "eval --out into a training run");
    assert_root_untouched(eval_cmd(&model, Some(Path::new("/"))), "eval --out /");

    // The default, twice: the second evaluation replaces the first.
    for _ in 0..2 {
        common::check(eval_cmd(&model, None).output().unwrap(), "eval");
    }
    let eval = run.join("eval");
    let mut names: Vec<String> = std::fs::read_dir(&eval)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name != LOCK_FILE)
        .collect();
    names.sort();
    assert_eq!(names, ["confusion.csv", "confusion.png", "eval.json"]);

    // Someone's file inside the run's eval/: --force keeps the whole run.
    std::fs::write(eval.join("notes.txt"), "mine").unwrap();
    let cmd = train_cmd(&run, &["--force"]);
    assert_refused_as_found(cmd, &run, "train --force over an eval/ holding notes.txt");
    // An eval/ of evaluations only: replaced with the run whose model it scored.
    std::fs::remove_file(eval.join("notes.txt")).unwrap();
    common::check(
        train_cmd(&run, &["--force"]).output().unwrap(),
        "train --force",
    );
    assert!(
        !eval.exists(),
        "the old run's evaluation outlived its model"
    );
    assert_run_complete(&run, 1);
}
