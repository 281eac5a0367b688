//! The feature cache serves a cached table only while it still describes its dataset: a cache
//! file with other columns, fewer rows, labels out of range, NaNs, other dtypes or a repeated
//! view is reported (path and reason), rebuilt, and the caller gets the freshly computed table.

use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use lgdm_pointcloud::cache::{FeatureCache, GOOD_BINS, GOOD_DIM};
use lgdm_pointcloud::dataset::{
    Dataset, DatasetError, DatasetSpec, generate, standard_collections,
};
use lgdm_pointcloud::features::{FeatureTable, good_features};
use lgdm_pointcloud::npz::{NpyRef, write_npz};

/// A small dataset (2 categories × 2 instances, 3 collections, 3 frames: 36 views) and its
/// GOOD table, made once.
fn dataset() -> &'static (tempfile::TempDir, Dataset, FeatureTable) {
    static DATA: OnceLock<(tempfile::TempDir, Dataset, FeatureTable)> = OnceLock::new();
    DATA.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let mut spec = DatasetSpec::small(5);
        spec.categories = vec!["mug".into(), "apple".into()];
        spec.instances_per_category = 2;
        spec.collections = standard_collections().into_iter().take(3).collect();
        spec.frames_per_sequence = 3;
        spec.grasp_images = 0;
        spec.previews = false;
        generate(&spec, dir.path(), &mut |_| {}).unwrap();
        let ds = Dataset::open(dir.path()).unwrap();
        let table = good_features(&ds, GOOD_BINS, &mut |_| {}).unwrap();
        assert_eq!(table.len(), 36);
        (dir, ds, table)
    })
}

/// The one cache file under `cache`.
fn cache_file(cache: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(cache.join("features"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "npz"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files.into_iter().next().unwrap()
}

/// What a corruption does to the clean table.
type Corrupt = fn(&mut FeatureTable);

/// A named way to write a corrupt cache file.
type WriteCorrupt = (&'static str, Box<dyn Fn()>);

fn corruptions() -> Vec<(&'static str, Corrupt)> {
    vec![
        ("10 columns", |t| {
            let n = t.len();
            t.features = (0..n)
                .flat_map(|i| t.features[i * t.dim..i * t.dim + 10].to_vec())
                .collect();
            t.dim = 10;
        }),
        ("fewer rows", |t| {
            let n = t.len() - 1;
            t.features.truncate(n * t.dim);
            t.collection.truncate(n);
            t.category.truncate(n);
            t.instance.truncate(n);
            t.sequence.truncate(n);
            t.frame.truncate(n);
        }),
        ("category 99", |t| t.category[4] = 99),
        ("a NaN", |t| t.features[3 * GOOD_DIM + 17] = f32::NAN),
        ("instance 99", |t| t.instance[0] = 99),
        ("collection 99", |t| t.collection[0] = 99),
        ("frame 99", |t| t.frame[1] = 99),
        ("another instance's category", |t| {
            t.category[0] = (t.category[0] + 1) % 2;
        }),
        ("a wrong sequence id", |t| t.sequence[2] += 1),
        // Issue 22: a reversed `frame` column was accepted (each view still once) and the
        // sequences were learnt backwards (test accuracy 92.3 → 88.5 %).
        ("the frame column reversed", |t| t.frame.reverse()),
        ("two frames swapped", |t| t.frame.swap(0, 1)),
        ("a repeated view", |t| {
            // Row 1 becomes a copy of row 0 (same count, same labels, one view missing).
            let row: Vec<f32> = t.row(0).to_vec();
            t.features[t.dim..2 * t.dim].copy_from_slice(&row);
            t.frame[1] = t.frame[0];
        }),
    ]
}

/// Writes `table` with its labels as uint64 instead of uint32 (numpy would read the same
/// values; the cache accepts only what it writes).
fn write_with_u64_labels(path: &Path, t: &FeatureTable) {
    let wide = |v: &[u32]| -> Vec<u64> { v.iter().map(|&x| u64::from(x)).collect() };
    let (c, cat, i, f) = (
        wide(&t.collection),
        wide(&t.category),
        wide(&t.instance),
        wide(&t.frame),
    );
    let (n, nd) = ([t.len()], [t.len(), t.dim]);
    write_npz(
        path,
        &[
            ("features", NpyRef::F32(&t.features, &nd)),
            ("collection", NpyRef::U64(&c, &n)),
            ("category", NpyRef::U64(&cat, &n)),
            ("instance", NpyRef::U64(&i, &n)),
            ("sequence", NpyRef::U64(&t.sequence, &n)),
            ("frame", NpyRef::U64(&f, &n)),
        ],
    )
    .unwrap();
}

/// Every corrupt version of the cache file, written over `path`, with its name.
fn corrupt_files(path: &Path, clean: &FeatureTable) -> Vec<WriteCorrupt> {
    let mut out: Vec<WriteCorrupt> = Vec::new();
    for (name, corrupt) in corruptions() {
        let (path, mut t) = (path.to_path_buf(), clean.clone());
        corrupt(&mut t);
        out.push((name, Box::new(move || t.write_npz(&path).unwrap())));
    }
    let (p, t) = (path.to_path_buf(), clean.clone());
    out.push((
        "uint64 labels",
        Box::new(move || write_with_u64_labels(&p, &t)),
    ));
    let p = path.to_path_buf();
    out.push((
        "garbage bytes",
        Box::new(move || std::fs::write(&p, b"PK\x03\x04 not really").unwrap()),
    ));
    out
}

#[test]
fn every_corruption_is_reported_with_the_path_and_rebuilt() {
    let (_, ds, clean) = dataset();
    let cache_dir = tempfile::tempdir().unwrap();
    let cache = FeatureCache::new(cache_dir.path());
    let computed = Cell::new(0);
    let compute = || -> Result<FeatureTable, DatasetError> {
        computed.set(computed.get() + 1);
        Ok(clean.clone())
    };
    let no_broken = &mut |p: &Path, r: String| panic!("{}: {r}", p.display());
    let first = cache
        .get_or_compute_with_dim(ds, "good", &[], GOOD_DIM, compute, no_broken)
        .unwrap();
    assert_eq!(&first, clean);
    let path = cache_file(cache_dir.path());
    for (name, write_corrupt) in corrupt_files(&path, clean) {
        write_corrupt();
        let before = computed.get();
        let mut broken: Vec<(PathBuf, String)> = Vec::new();
        let got = cache
            .get_or_compute_with_dim(ds, "good", &[], GOOD_DIM, compute, &mut |p, r| {
                broken.push((p.to_path_buf(), r))
            })
            .unwrap();
        assert_eq!(broken.len(), 1, "{name}: reported once");
        assert_eq!(broken[0].0, path, "{name}: the cache file is named");
        assert!(!broken[0].1.is_empty(), "{name}: with a reason");
        assert_eq!(computed.get(), before + 1, "{name}: computed again");
        assert!(&got == clean, "{name}: the clean table is returned");
        // Rewritten: the next call is served from the cache.
        assert_eq!(&FeatureTable::read_npz(&path).unwrap(), clean, "{name}");
        let again = cache
            .get_or_compute_with_dim(ds, "good", &[], GOOD_DIM, compute, no_broken)
            .unwrap();
        assert_eq!(&again, clean, "{name}");
        assert_eq!(computed.get(), before + 1, "{name}: served from the cache");
    }
}

#[test]
fn the_reasons_say_what_does_not_match() {
    let (_, ds, clean) = dataset();
    let cache_dir = tempfile::tempdir().unwrap();
    let cache = FeatureCache::new(cache_dir.path());
    cache.good_features(ds, &mut |_| {}).unwrap();
    let path = cache_file(cache_dir.path());
    let expected = [
        ("10 columns", "10 columns, the encoder gives 675"),
        ("fewer rows", "35 rows, the dataset has 36 views"),
        ("category 99", "row 4: category 99 out of range"),
        ("a NaN", "row 3, column 17"),
        ("the frame column reversed", "comes after its frame"),
        (
            "two frames swapped",
            "row 1: collection 0, instance 0, frame 0 comes after its frame 1",
        ),
    ];
    for (name, corrupt) in corruptions() {
        let Some((_, want)) = expected.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        let mut t = clean.clone();
        corrupt(&mut t);
        t.write_npz(&path).unwrap();
        let mut reasons = Vec::new();
        cache
            .get_or_compute_with_dim(
                ds,
                "good",
                &[],
                GOOD_DIM,
                || Ok::<_, DatasetError>(clean.clone()),
                &mut |_, r| reasons.push(r),
            )
            .unwrap();
        assert!(
            reasons.len() == 1 && reasons[0].contains(want),
            "{name}: {reasons:?}"
        );
    }
}

#[test]
fn good_features_never_serves_a_corrupt_cache() {
    let (_, ds, clean) = dataset();
    let cache_dir = tempfile::tempdir().unwrap();
    let cache = FeatureCache::new(cache_dir.path());
    assert_eq!(&cache.good_features(ds, &mut |_| {}).unwrap(), clean);
    let path = cache_file(cache_dir.path());
    for (name, write_corrupt) in corrupt_files(&path, clean) {
        write_corrupt();
        let got = cache.good_features(ds, &mut |_| {}).unwrap();
        assert!(&got == clean, "{name}: a corrupt cache was served");
        assert_eq!(&FeatureTable::read_npz(&path).unwrap(), clean, "{name}");
    }
}

#[test]
fn get_or_compute_without_a_dimension_still_checks_rows_labels_and_values() {
    let (_, ds, clean) = dataset();
    let cache_dir = tempfile::tempdir().unwrap();
    let cache = FeatureCache::new(cache_dir.path());
    let compute = || Ok::<_, DatasetError>(clean.clone());
    cache
        .get_or_compute(ds, "good", &[], compute, &mut |_, _| {})
        .unwrap();
    let path = cache_file(cache_dir.path());
    for (name, corrupt) in corruptions() {
        if name == "10 columns" {
            continue; // Needs the encoder's dimension: get_or_compute_with_dim.
        }
        let mut t = clean.clone();
        corrupt(&mut t);
        t.write_npz(&path).unwrap();
        let mut broken = Vec::new();
        let got = cache
            .get_or_compute(ds, "good", &[], compute, &mut |p, _| {
                broken.push(p.to_path_buf())
            })
            .unwrap();
        assert_eq!(broken, vec![path.clone()], "{name}");
        assert!(&got == clean, "{name}");
    }
}

#[test]
fn a_computed_table_that_does_not_match_is_an_error_and_is_not_stored() {
    let (_, ds, clean) = dataset();
    let cache_dir = tempfile::tempdir().unwrap();
    let cache = FeatureCache::new(cache_dir.path());
    for (name, corrupt) in corruptions() {
        let mut t = clean.clone();
        corrupt(&mut t);
        let err = cache
            .get_or_compute_with_dim(
                ds,
                "good",
                &[],
                GOOD_DIM,
                || Ok::<_, DatasetError>(t),
                &mut |_, _| {},
            )
            .unwrap_err();
        assert!(
            matches!(err, DatasetError::FeatureTable { .. }),
            "{name}: {err}"
        );
        assert!(
            !cache_dir.path().join("features").exists()
                || std::fs::read_dir(cache_dir.path().join("features"))
                    .unwrap()
                    .next()
                    .is_none(),
            "{name}: nothing stored"
        );
    }
}
