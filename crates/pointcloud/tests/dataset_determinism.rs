//! Same seed → byte-identical dataset; another seed → different data. A failed run leaves no
//! collection file behind.

use std::collections::BTreeMap;
use std::path::Path;

use lgdm_pointcloud::dataset::{DatasetError, DatasetSpec, generate, standard_collections};

fn tiny_spec(seed: u64) -> DatasetSpec {
    let mut spec = DatasetSpec::small(seed);
    spec.categories = vec!["bottle".into(), "apple".into()];
    spec.instances_per_category = 1;
    spec.collections = standard_collections().into_iter().step_by(3).collect();
    spec.frames_per_sequence = 2;
    spec.grasp_images = 2;
    spec
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

#[test]
fn same_seed_same_bytes() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    generate(&tiny_spec(42), a.path(), &mut |_| {}).unwrap();
    generate(&tiny_spec(42), b.path(), &mut |_| {}).unwrap();
    generate(&tiny_spec(43), c.path(), &mut |_| {}).unwrap();
    let (fa, fb, fc) = (files(a.path()), files(b.path()), files(c.path()));
    assert!(fa.len() >= 6, "{:?}", fa.keys());
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (name, bytes) in &fa {
        assert!(
            bytes == &fb[name],
            "{name} differs between two runs with the same seed"
        );
    }
    assert!(
        fa.iter()
            .filter(|(n, _)| n.ends_with(".mcap"))
            .all(|(n, bytes)| bytes != &fc[n])
    );
}

#[test]
fn failed_run_leaves_no_collection_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = tiny_spec(1);
    // A camera that looks away from the turntable: no object pixel, an error on the first view.
    spec.camera.target_height_m = 5.0;
    let err = generate(&spec, dir.path(), &mut |_| {}).unwrap_err();
    assert!(matches!(err, DatasetError::EmptyView { .. }), "{err}");
    let left = files(dir.path());
    assert!(left.is_empty(), "left behind: {:?}", left.keys());
}

#[test]
fn invalid_specs_name_the_field() {
    let mut spec = tiny_spec(1);
    spec.frames_per_sequence = 0;
    let err = spec.validate().unwrap_err().to_string();
    assert!(err.contains("frames_per_sequence"), "{err}");
    let mut spec = tiny_spec(1);
    spec.categories.push("spaceship".into());
    assert!(
        spec.validate()
            .unwrap_err()
            .to_string()
            .contains("spaceship")
    );
    assert!(DatasetSpec::preset("huge", 0).is_err());
}
