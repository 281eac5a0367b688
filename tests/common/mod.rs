//! Helpers shared by the end-to-end tests that drive the real `lgdm` binary (`e2e`, `e2e_ae`,
//! `sim_e2e`, `sim_pickplace_e2e`).
//! Each test binary includes this file with `#[path]` and uses what it needs.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `lgdm` binary under test, with its feature cache in `cache`.
pub fn lgdm(cache: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lgdm"));
    c.env("LGDM_CACHE_DIR", cache);
    c
}

/// A scratch directory for this test binary: `<cargo tmp>/<tag>-<pid>`, created.
pub fn work_dir(tag: &str) -> PathBuf {
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A tiny dataset generated at `dir` (small preset, 2 frames per sequence: 900 views, no grasp
/// images; seed 5), with the feature cache in `cache`.
pub fn tiny_dataset(dir: &Path, cache: &Path) {
    check(
        lgdm(cache)
            .args(["gen-dataset", "--preset", "small", "--frames", "2"])
            .args(["--grasp-images", "0", "--seed", "5", "--progress", "none"])
            .arg("--out")
            .arg(dir)
            .output()
            .unwrap(),
        "gen-dataset",
    );
}

/// Panics, showing both streams, unless the command succeeded.
pub fn check(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed ({}):\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// metrics.json without what differs between two runs of one experiment: the wall-clock fields
/// and the dataset path.
pub fn without_times(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| {
                    !matches!(
                        k.as_str(),
                        "seconds" | "train_seconds" | "inference_ms_per_sample" | "dataset"
                    )
                })
                .map(|(k, v)| (k.clone(), without_times(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(without_times).collect()),
        other => other.clone(),
    }
}

/// A run directory's results.json.
pub fn read_results(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A sim run's results.json without the wall-clock fields (every object named `wall`).
pub fn without_wall(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| k.as_str() != "wall")
                .map(|(k, v)| (k.clone(), without_wall(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(without_wall).collect()),
        other => other.clone(),
    }
}

/// A sim rate (`successes`, `trials`, `value`, Wilson interval) is consistent.
pub fn assert_rate(rate: &serde_json::Value, what: &str) {
    let trials = rate["trials"]
        .as_u64()
        .unwrap_or_else(|| panic!("{what}: {rate}"));
    let successes = rate["successes"].as_u64().unwrap();
    assert!(successes <= trials, "{what}: {rate}");
    let (lo, hi) = (
        rate["wilson_low"].as_f64().unwrap(),
        rate["wilson_high"].as_f64().unwrap(),
    );
    assert!(
        (0.0..=1.0).contains(&lo) && (0.0..=1.0).contains(&hi) && lo <= hi,
        "{what}: {rate}"
    );
    if trials > 0 {
        let v = rate["value"].as_f64().unwrap();
        assert!(
            (v - successes as f64 / trials as f64).abs() < 1e-12,
            "{what}: {rate}"
        );
        assert!(lo <= v && v <= hi, "{what}: {rate}");
    }
}
