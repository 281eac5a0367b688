//! `--encoder ae` and `--grasp network` end to end through the real `lgdm` binary built with the
//! `ae` feature: `lgdm features` writes one finite, unit-norm 256-d row per view with the GOOD
//! table's labels in the same order; the feature cache is keyed by the checkpoint's bytes; a short
//! `lgdm train --scenario ni` runs on these features and records the checkpoint; a missing
//! checkpoint or Python module is an error that names it; `lgdm sim grasp --grasp network` plays
//! isolated rounds with the shipped network, every attempt with a grasp in the crop or the reason
//! none was found. Needs numpy, torch and train_ae in the venv (`$VIRTUAL_ENV`,
//! `$LGDM_VENV` or ~/.cache/lgdm/venv): `cargo test --release -p lgdm-cli --features ae --test
//! e2e_ae`.

use lgdm_pointcloud::features::FeatureTable;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

#[path = "common/mod.rs"]
mod common;
use common::{check, lgdm};

fn work_dir() -> PathBuf {
    common::work_dir("e2e-ae")
}

/// The venv the binary's embedded Python uses (same search as `lgdm_pybridge::ae::venv_dir`).
fn venv_python() -> PathBuf {
    let venv = [
        std::env::var_os("VIRTUAL_ENV").map(PathBuf::from),
        std::env::var_os("LGDM_VENV").map(PathBuf::from),
        std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/lgdm/venv")),
    ]
    .into_iter()
    .flatten()
    .find(|p| p.is_dir())
    .expect("no venv: set VIRTUAL_ENV or LGDM_VENV to one with torch and train_ae");
    venv.join("bin").join("python")
}

/// A seeded, untrained `cpu`-configuration checkpoint written by train_ae's own writer.
fn checkpoint(seed: u32) -> PathBuf {
    let path = work_dir().join(format!("ae-seed{seed}.pt"));
    let script = format!(
        "import sys, torch\n\
         from train_ae.model import GraspAutoencoder, ModelConfig\n\
         from train_ae.checkpoint import save_checkpoint\n\
         torch.manual_seed({seed})\n\
         save_checkpoint(sys.argv[1], GraspAutoencoder(ModelConfig.preset('cpu')), {{}})\n"
    );
    check(
        Command::new(venv_python())
            .arg("-c")
            .arg(script)
            .arg(&path)
            .output()
            .unwrap(),
        "writing a checkpoint",
    );
    path
}

fn checkpoint_a() -> &'static Path {
    static A: OnceLock<PathBuf> = OnceLock::new();
    A.get_or_init(|| checkpoint(0))
}

/// A tiny dataset: small preset, 2 frames per sequence (900 views), no grasp images.
fn tiny_dataset() -> &'static Path {
    static DATA: OnceLock<PathBuf> = OnceLock::new();
    DATA.get_or_init(|| {
        let dir = work_dir().join("tiny");
        common::tiny_dataset(&dir, &work_dir().join("cache-gen"));
        dir
    })
}

fn features(cache: &Path, encoder: &str, ckpt: Option<&Path>, out: &Path) -> Output {
    let mut c = lgdm(cache);
    c.args(["features", "--progress", "none", "--encoder", encoder])
        .arg("--dataset")
        .arg(tiny_dataset())
        .arg("--out")
        .arg(out);
    if let Some(p) = ckpt {
        c.arg("--ae-checkpoint").arg(p);
    }
    c.output().unwrap()
}

fn cached_ae_tables(cache: &Path) -> usize {
    std::fs::read_dir(cache.join("features")).map_or(0, |d| {
        d.filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with("-ae.npz")
        })
        .count()
    })
}

/// The feature cache shared by the tests that use checkpoint A.
fn shared_cache() -> PathBuf {
    work_dir().join("cache")
}

/// `lgdm features --encoder ae` with checkpoint A, run once (it fills the shared cache).
fn features_a() -> &'static FeatureTable {
    static A: OnceLock<FeatureTable> = OnceLock::new();
    A.get_or_init(|| {
        let out = work_dir().join("a.npz");
        check(
            features(&shared_cache(), "ae", Some(checkpoint_a()), &out),
            "features --encoder ae",
        );
        FeatureTable::read_npz(&out).unwrap()
    })
}

#[test]
fn features_are_unit_256d_rows_in_good_order_cached_per_checkpoint() {
    let dir = work_dir().join("features");
    std::fs::create_dir_all(&dir).unwrap();
    let cache = shared_cache();
    check(
        features(&cache, "good", None, &dir.join("good.npz")),
        "features --encoder good",
    );
    let good = FeatureTable::read_npz(&dir.join("good.npz")).unwrap();
    let a = features_a();
    assert_eq!(a.dim, 256);
    assert_eq!(a.len(), 900, "one row per view");
    for (name, x, y) in [
        ("collection", &a.collection, &good.collection),
        ("category", &a.category, &good.category),
        ("instance", &a.instance, &good.instance),
        ("frame", &a.frame, &good.frame),
    ] {
        assert_eq!(x, y, "column {name} differs from the GOOD table's");
    }
    assert_eq!(a.sequence, good.sequence);
    for i in 0..a.len() {
        let row = a.row(i);
        assert!(row.iter().all(|v| v.is_finite()), "row {i} is not finite");
        let norm = row.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((norm - 1.0).abs() < 1e-3, "row {i} has norm {norm}");
    }
    assert_ne!(
        a.row(0),
        a.row(a.len() - 1),
        "different views, same feature"
    );
    assert_eq!(cached_ae_tables(&cache), 1);

    // Same checkpoint: the cached table, identical. Another checkpoint: a new cache entry.
    check(
        features(&cache, "ae", Some(checkpoint_a()), &dir.join("a2.npz")),
        "features --encoder ae (cached)",
    );
    assert_eq!(&FeatureTable::read_npz(&dir.join("a2.npz")).unwrap(), a);
    let b_ckpt = checkpoint(1);
    check(
        features(&cache, "ae", Some(&b_ckpt), &dir.join("b.npz")),
        "features --encoder ae, second checkpoint",
    );
    assert_eq!(cached_ae_tables(&cache), 2);
    let b = FeatureTable::read_npz(&dir.join("b.npz")).unwrap();
    assert_ne!(a.features, b.features);
}

#[test]
fn train_ni_runs_on_ae_features_and_records_the_checkpoint() {
    let dir = work_dir().join("train");
    std::fs::create_dir_all(&dir).unwrap();
    let run = dir.join("run");
    features_a(); // the features come from the shared cache
    check(
        lgdm(&shared_cache())
            .args([
                "train",
                "--scenario",
                "ni",
                "--encoder",
                "ae",
                "--trials",
                "1",
            ])
            .args(["--progress", "none", "--ae-checkpoint"])
            .arg(checkpoint_a())
            .arg("--dataset")
            .arg(tiny_dataset())
            .arg("--out")
            .arg(&run)
            .output()
            .unwrap(),
        "train --encoder ae",
    );
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["encoder"], "ae");
    let trial = &metrics["trials"][0];
    assert_eq!(
        trial["steps"].as_array().unwrap().len(),
        12,
        "one step per training collection"
    );
    let acc = trial["test"]["category_accuracy_sm"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&acc), "category accuracy {acc}");
    assert!(trial["episodic_nodes"].as_u64().unwrap() >= 2);
    let config = std::fs::read_to_string(run.join("config.toml")).unwrap();
    let ckpt = std::fs::canonicalize(checkpoint_a()).unwrap();
    assert!(
        config.contains(&format!("ae_checkpoint = \"{}\"", ckpt.display())),
        "config.toml does not name the checkpoint:\n{config}"
    );
    assert!(config.contains("ae_checkpoint_fnv1a = "), "{config}");
    // config.toml still passes back as --config.
    check(
        lgdm(&dir.join("cache"))
            .args([
                "train",
                "--scenario",
                "ni",
                "--encoder",
                "ae",
                "--trials",
                "1",
            ])
            .args(["--progress", "none", "--epochs", "1", "--config"])
            .arg(run.join("config.toml"))
            .arg("--ae-checkpoint")
            .arg(checkpoint_a())
            .arg("--dataset")
            .arg(tiny_dataset())
            .arg("--out")
            .arg(dir.join("run2"))
            .output()
            .unwrap(),
        "train --config <run>/config.toml",
    );
}

#[test]
fn missing_checkpoint_or_module_is_named() {
    let dir = work_dir().join("errors");
    std::fs::create_dir_all(&dir).unwrap();
    let out = features(
        &dir.join("cache"),
        "ae",
        Some(&dir.join("no-such.pt")),
        &dir.join("x.npz"),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such.pt"), "{err}");
    assert!(!dir.join("x.npz").exists());

    // No venv anywhere: the error names the module that is missing and how to install it.
    let empty = dir.join("empty-venv");
    std::fs::create_dir_all(&empty).unwrap();
    let out = lgdm(&dir.join("cache"))
        .args(["features", "--progress", "none", "--encoder", "ae"])
        .arg("--ae-checkpoint")
        .arg(checkpoint_a())
        .arg("--dataset")
        .arg(tiny_dataset())
        .arg("--out")
        .arg(dir.join("y.npz"))
        .env("VIRTUAL_ENV", &empty)
        .env("LGDM_VENV", &empty)
        .env("HOME", &empty)
        .env_remove("PYTHONPATH")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("could not be imported"), "{err}");
    assert!(err.contains("pip install"), "{err}");
    assert!(err.contains(&*empty.to_string_lossy()), "{err}");
}

#[test]
fn without_ae_checkpoint_the_shipped_one_is_used_or_the_flag_is_named() {
    let dir = work_dir().join("default");
    std::fs::create_dir_all(&dir).unwrap();
    let out = features(&dir.join("cache"), "ae", None, &dir.join("d.npz"));
    if out.status.success() {
        assert_eq!(FeatureTable::read_npz(&dir.join("d.npz")).unwrap().dim, 256);
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--ae-checkpoint"), "{err}");
    }
}

/// `lgdm sim grasp --grasp network` with the shipped checkpoint: results.json names the source,
/// every attempt tried a network grasp (crop pixels, jaw = the finger width in the 224-px crop)
/// or failed with `no_grasp_found`; a missing `--ae-checkpoint` is named before any round runs.
#[test]
fn sim_grasp_network_plays_isolated_rounds() {
    let dir = work_dir().join("sim");
    std::fs::create_dir_all(&dir).unwrap();
    let sim = |out: &Path, extra: &[&str]| {
        lgdm(&dir.join("cache"))
            .args([
                "sim",
                "grasp",
                "--scenario",
                "isolated",
                "--grasp",
                "network",
            ])
            .args(["--rounds", "3", "--seed", "0", "--progress", "none"])
            .args(extra)
            .arg("--out")
            .arg(out)
            .env("OMP_NUM_THREADS", "1")
            .output()
            .unwrap()
    };
    let out = dir.join("run");
    check(sim(&out, &[]), "sim grasp --grasp network");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(results["run"]["grasp_source"], "network");
    let attempts = results["attempts"].as_array().unwrap();
    assert!(!attempts.is_empty(), "no attempt in 3 rounds");
    assert_eq!(results["summary"]["attempts"], attempts.len());
    let mut tried = 0;
    for a in attempts {
        let grasp = &a["grasp"];
        if grasp.is_null() {
            assert_eq!(
                a["reason"], "no_grasp_found",
                "attempt without a grasp: {a}"
            );
            continue;
        }
        tried += 1;
        let g = &grasp["crop"];
        let c = g["center_px"].as_array().unwrap();
        for v in c {
            let v = v.as_f64().unwrap();
            assert!((0.0..224.0).contains(&v), "centre outside the crop: {g}");
        }
        // The shipped checkpoint's jaw: 0.02 m of the 0.22 m crop, in its 224 px.
        let jaw = g["jaw_px"].as_f64().unwrap();
        assert!(
            (jaw - 224.0 * 0.02 / 0.22).abs() < 0.05,
            "jaw {jaw} px: {g}"
        );
        assert!(g["width_px"].as_f64().unwrap() >= 0.0, "{g}");
        assert!(
            g["quality"].as_f64().unwrap() >= 0.2,
            "below the threshold: {g}"
        );
        if !a["grasp_success"].as_bool().unwrap() {
            assert!(
                a["reason"].is_string(),
                "failed attempt without a reason: {a}"
            );
        }
    }
    assert!(tried > 0, "the network proposed no grasp in 3 rounds");

    let missing = dir.join("no-such.pt");
    let err = sim(
        &dir.join("run2"),
        &["--ae-checkpoint", missing.to_str().unwrap()],
    );
    assert!(!err.status.success());
    let text = String::from_utf8_lossy(&err.stderr);
    assert!(text.contains("no-such.pt"), "{text}");
    assert!(!dir.join("run2").exists());
}

/// `lgdm sim pick-place --encoder ae`: the robot recognises with the autoencoder's 256-d
/// features (the pipeline `lgdm features --encoder ae` runs on a dataset's views): the run
/// records the encoder, saves a 256-d model whose record says `ae`, and a second run starts from
/// it; that model is refused with `--encoder good`, naming the encoder.
#[test]
fn pick_place_recognises_with_the_autoencoder() {
    let dir = work_dir().join("pick-place");
    std::fs::create_dir_all(&dir).unwrap();
    let pick_place = |out: &Path, extra: &[&str]| {
        lgdm(&dir.join("cache"))
            .args(["sim", "pick-place", "--seed", "0", "--progress", "none"])
            .args(["--objects", "5"])
            .args(extra)
            .arg("--out")
            .arg(out)
            .env("OMP_NUM_THREADS", "1")
            .output()
            .unwrap()
    };
    let a = dir.join("a");
    check(
        pick_place(&a, &["--rounds", "2", "--encoder", "ae"]),
        "pick-place --encoder ae",
    );
    let r = common::read_results(&a);
    assert_eq!(r["recognition"]["encoder"], "ae");
    let looks = r["summary"]["recognition_accuracy"]["trials"]
        .as_u64()
        .unwrap();
    assert!(looks >= 2, "{}", r["summary"]);
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("model.json")).unwrap()).unwrap();
    assert_eq!(model["encoder"], "ae");
    let gdm = lgdm_gdm::Gdm::load(&a.join("model.lgdm")).unwrap();
    assert_eq!(gdm.dim(), 256);
    assert!(gdm.episodic().len() >= 2);
    // The second round's objects are the first's: the robot was taught them.
    let known = r["attempts"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|x| x.get("recognition"))
        .filter(|rec| rec["first_look"] == true && rec["guess"]["known"] == true)
        .count();
    assert!(known >= 1, "nothing recognised in the second round");

    let model_path = a.join("model.lgdm");
    let b = dir.join("b");
    check(
        pick_place(
            &b,
            &[
                "--rounds",
                "1",
                "--encoder",
                "ae",
                "--model",
                model_path.to_str().unwrap(),
            ],
        ),
        "pick-place --encoder ae --model",
    );
    let rb = common::read_results(&b);
    assert_eq!(
        rb["recognition"]["memory"][0]["episodic_nodes"].as_u64(),
        Some(gdm.episodic().len() as u64)
    );

    let c = dir.join("c");
    let e = pick_place(
        &c,
        &["--rounds", "1", "--model", model_path.to_str().unwrap()],
    );
    let msg = String::from_utf8_lossy(&e.stderr);
    assert!(!e.status.success(), "{msg}");
    assert!(
        msg.contains("`ae` encoder") && msg.contains("--encoder ae"),
        "{msg}"
    );
    assert!(!c.exists());
}
