//! GOOD feature tables are bounded where their size enters: `bins` outside 1..=256, or a table
//! larger than an `.npz` holds (4 GiB), is refused with a typed error naming `bins` before any
//! view is read.

use lgdm_pointcloud::dataset::{
    Dataset, DatasetError, DatasetSpec, MANIFEST_FILE, generate, standard_collections,
};
use lgdm_pointcloud::features::good_features;

fn tiny_dataset(dir: &std::path::Path) {
    let mut spec = DatasetSpec::small(9);
    spec.categories = vec!["mug".into(), "bowl".into()];
    spec.instances_per_category = 1;
    spec.collections = standard_collections().into_iter().take(1).collect();
    spec.frames_per_sequence = 2;
    spec.grasp_images = 0;
    spec.previews = false;
    generate(&spec, dir, &mut |_| {}).unwrap();
}

fn refused_for_bins(r: Result<lgdm_pointcloud::features::FeatureTable, DatasetError>) -> String {
    match r {
        Err(e @ DatasetError::InvalidSpec { field: "bins", .. }) => e.to_string(),
        other => panic!("not refused for `bins`: {:?}", other.map(|t| t.dim)),
    }
}

#[test]
fn bins_outside_the_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    tiny_dataset(dir.path());
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(good_features(&ds, 256, &mut |_| {}).unwrap().dim, 196_608);
    for bins in [257, 100_000, 0] {
        let e = refused_for_bins(good_features(&ds, bins, &mut |_| {}));
        assert!(e.contains("1..=256"), "{e}");
    }
}

#[test]
fn a_table_larger_than_an_npz_holds_is_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    tiny_dataset(dir.path());
    // The manifest now claims 100,000 frames per sequence (200,000 views); the files still
    // hold 2, so reading anything would fail with another error.
    let path = dir.path().join(MANIFEST_FILE);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    m["frames_per_sequence"] = 100_000.into();
    m["views"] = 200_000.into();
    m["collections"][0]["views"] = 200_000.into();
    std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
    let ds = Dataset::open(dir.path()).unwrap();
    // 200,000 × 3 × 60² × 4 B = 8.0 GiB.
    let e = refused_for_bins(good_features(&ds, 60, &mut |_| {}));
    assert!(e.contains("GiB") && e.contains(".npz"), "{e}");
    // A small enough table gets to the files, which do not hold the claimed frames.
    assert!(matches!(
        good_features(&ds, 2, &mut |_| {}),
        Err(DatasetError::Corrupt { .. })
    ));
}
