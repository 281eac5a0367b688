//! End-to-end tests of `lgdm sim pick-place`, driving the real binary: a two-round run from an
//! empty model writes `results.json` whose attempts carry the recognition (true and predicted
//! labels, confidence, the teacher's part) and whose summary holds the first-guess accuracy, the
//! teacher interventions, grasp and placement rates and the cleared fraction with Wilson
//! intervals; it saves the learnt model as a dual-memory checkpoint that loads and that a second
//! run starts from; the same seed gives the same results (wall-clock fields aside); bad input
//! (`--rounds 0`, `--attempts 0`, a `--model` of another feature dimension, a model trained with
//! another encoder) fails with a message naming the problem and writes nothing.
//!
//! Run in release (`cargo test --release -p lgdm-cli --test sim_pickplace_e2e`): the physics is
//! slow in a debug build.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

#[path = "common/mod.rs"]
mod common;
use common::{assert_rate, check, lgdm, read_results, without_wall};

fn work_dir() -> PathBuf {
    common::work_dir("sim-pickplace-e2e")
}

fn pick_place(out: &Path, args: &[&str]) -> Output {
    lgdm(&work_dir().join("cache"))
        .args(["sim", "pick-place", "--progress", "none"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A checkpoint of an untrained-but-non-empty model of feature dimension `dim`.
fn write_model(path: &Path, dim: usize) {
    let mut gdm = lgdm_gdm::Gdm::new(lgdm_gdm::GdmConfig::default(), dim).unwrap();
    let a = vec![0.0f32; dim];
    let b = vec![0.01f32; dim];
    gdm.train(&[
        lgdm_gdm::Sample::labelled(&a, 0, 0, 0),
        lgdm_gdm::Sample::labelled(&b, 0, 0, 0),
    ])
    .unwrap();
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    gdm.save(path).unwrap();
}

#[test]
fn pick_place_recognises_is_taught_and_saves_the_model() {
    let dir = work_dir();
    let a = dir.join("run-a");
    let out = check(
        pick_place(&a, &["--rounds", "2", "--seed", "3"]),
        "pick-place",
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("recognition (category)"), "{stdout}");
    let r = read_results(&a);
    let s = &r["summary"];
    let attempts = s["attempts"].as_u64().unwrap();
    assert!(attempts >= 2, "{s}");
    for key in [
        "recognition_accuracy",
        "instance_recognition_accuracy",
        "teacher_intervention_rate",
        "grasp_success_rate",
        "placement_success_rate",
        "cleared_fraction",
    ] {
        assert_rate(&s[key], key);
    }
    let looks = s["recognition_accuracy"]["trials"].as_u64().unwrap();
    let taught = s["teacher_interventions"].as_u64().unwrap();
    // An empty model knows nothing: the first object is always taught.
    assert!(looks >= 1 && taught >= 1 && taught <= looks, "{s}");
    assert_eq!(s["cleared_fraction"]["trials"].as_u64(), Some(10), "{s}");
    let list = r["attempts"].as_array().unwrap();
    assert_eq!(list.len() as u64, attempts);
    let first = list
        .iter()
        .find_map(|a| a.get("recognition"))
        .expect("an attempt with a recognition");
    for key in [
        "true_category",
        "true_instance",
        "guess",
        "category_correct",
        "instance_correct",
        "teacher",
        "taught_views",
        "first_look",
    ] {
        assert!(first.get(key).is_some(), "recognition lacks {key}: {first}");
    }
    assert_eq!(first["teacher"], Value::Bool(true), "{first}");
    assert_eq!(first["guess"]["known"], Value::Bool(false), "{first}");
    for a in list {
        assert!(a.get("reason").is_some() && a.get("placement_success").is_some());
    }
    let rec = &r["recognition"];
    assert_eq!(rec["encoder"], "good");
    assert_eq!(rec["start_model"], "empty");
    let memory = rec["memory"].as_array().unwrap();
    assert_eq!(memory.len(), 3, "start + one point per round: {rec}");
    assert!(memory[2]["episodic_nodes"].as_u64().unwrap() >= 2);
    for file in [
        "model.lgdm",
        "model.json",
        "learning_curve.png",
        "nodes.png",
        "summary.txt",
    ] {
        assert!(a.join(file).is_file(), "{file} missing");
    }
    // The model loads with the library's checkpoint reader, with the run's node counts.
    let gdm = lgdm_gdm::Gdm::load(&a.join("model.lgdm")).unwrap();
    assert_eq!(gdm.dim(), 675);
    assert_eq!(
        gdm.episodic().len() as u64,
        memory[2]["episodic_nodes"].as_u64().unwrap()
    );

    // Same seed, same results.
    let b = dir.join("run-b");
    check(
        pick_place(&b, &["--rounds", "2", "--seed", "3"]),
        "pick-place again",
    );
    assert_eq!(without_wall(&r), without_wall(&read_results(&b)));
    assert_eq!(
        std::fs::read(a.join("model.lgdm")).unwrap(),
        std::fs::read(b.join("model.lgdm")).unwrap()
    );

    // A second run starts from the learnt model and its label names.
    let c = dir.join("run-c");
    let model = a.join("model.lgdm");
    check(
        pick_place(
            &c,
            &[
                "--rounds",
                "1",
                "--seed",
                "4",
                "--model",
                model.to_str().unwrap(),
            ],
        ),
        "pick-place from a model",
    );
    let rc = read_results(&c);
    assert_eq!(
        rc["recognition"]["memory"][0]["episodic_nodes"],
        memory[2]["episodic_nodes"]
    );
    assert_eq!(
        rc["recognition"]["start_model"],
        model.display().to_string()
    );
}

#[test]
fn bad_input_is_refused_before_anything_is_written() {
    let dir = work_dir();
    let out = dir.join("bad");
    let e = pick_place(&out, &["--rounds", "0"]);
    assert!(
        !e.status.success() && stderr(&e).contains("--rounds 0"),
        "{}",
        stderr(&e)
    );
    let e = pick_place(&out, &["--attempts", "0"]);
    assert!(
        !e.status.success() && stderr(&e).contains("--attempts 0"),
        "{}",
        stderr(&e)
    );

    // A model of the autoencoder's dimension.
    let ae_dim = dir.join("ae-model").join("model-trial0.lgdm");
    write_model(&ae_dim, 256);
    let e = pick_place(
        &out,
        &["--rounds", "1", "--model", ae_dim.to_str().unwrap()],
    );
    let msg = stderr(&e);
    assert!(!e.status.success(), "{msg}");
    assert!(msg.contains("256-d") && msg.contains("675-d"), "{msg}");

    // A model whose run says it was trained with another encoder.
    let other = dir.join("other-encoder").join("model-trial0.lgdm");
    write_model(&other, 675);
    std::fs::write(
        other.parent().unwrap().join("metrics.json"),
        r#"{"encoder": "ae", "categories": ["mug"], "instances": ["mug_01"]}"#,
    )
    .unwrap();
    let e = pick_place(&out, &["--rounds", "1", "--model", other.to_str().unwrap()]);
    let msg = stderr(&e);
    assert!(!e.status.success(), "{msg}");
    assert!(
        msg.contains("`ae` encoder") && msg.contains("good"),
        "{msg}"
    );

    let e = pick_place(&out, &["--rounds", "1", "--scenario", "isolated"]);
    assert!(!e.status.success() && stderr(&e).contains("isolated"));
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}
