//! A default build (no cargo feature `ae`) does not link libpython, and refuses `--encoder ae`
//! before reading or generating any data, saying how to rebuild and what to install.
#![cfg(not(feature = "ae"))]

use std::path::PathBuf;
use std::process::Command;

fn tmp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("encoder-ae-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn assert_rebuild_message(stderr: &[u8]) {
    let err = String::from_utf8_lossy(stderr);
    for needle in [
        "built without the `ae` feature",
        "cargo build --release -p lgdm-cli --features ae",
        "pip install -e python/train_ae",
        "docs/guide/grasp-network.md",
    ] {
        assert!(err.contains(needle), "missing {needle:?} in: {err}");
    }
}

#[test]
fn features_and_train_say_how_to_rebuild() {
    let dir = tmp("msg");
    let cache = dir.join("cache");
    let out = Command::new(env!("CARGO_BIN_EXE_lgdm"))
        .env("LGDM_CACHE_DIR", &cache)
        .args(["features", "--encoder", "ae", "--progress", "none"])
        .arg("--dataset")
        .arg(dir.join("no-dataset"))
        .arg("--out")
        .arg(dir.join("f.npz"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert_rebuild_message(&out.stderr);
    assert!(!dir.join("f.npz").exists());

    let out = Command::new(env!("CARGO_BIN_EXE_lgdm"))
        .env("LGDM_CACHE_DIR", &cache)
        .args([
            "train",
            "--scenario",
            "ni",
            "--encoder",
            "ae",
            "--progress",
            "none",
        ])
        .arg("--out")
        .arg(dir.join("run"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert_rebuild_message(&out.stderr);
    // It failed before generating the embedded dataset or creating the run directory.
    assert!(!cache.exists(), "the cache directory was written");
    assert!(!dir.join("run").exists());
}

#[test]
fn default_binary_does_not_link_libpython() {
    let Ok(out) = Command::new("ldd").arg(env!("CARGO_BIN_EXE_lgdm")).output() else {
        return; // no ldd on this system: nothing to check with
    };
    let libs = String::from_utf8_lossy(&out.stdout);
    assert!(!libs.is_empty(), "ldd printed nothing");
    assert!(
        !libs.contains("libpython"),
        "the default lgdm links libpython:\n{libs}"
    );
}
