//! GOOD features of a generated dataset: one 675-value row per view with its labels, written
//! as `.npz` that reads back identically here and that numpy loads (checked when a Python with
//! numpy is available: `LGDM_PYTHON`, the project venv, or `python3`).

use std::process::Command;

use lgdm_pointcloud::dataset::{Dataset, DatasetSpec, generate, standard_collections};
use lgdm_pointcloud::features::{FeatureTable, good_features};

fn python_with_numpy() -> Option<String> {
    let home = std::env::var("HOME").unwrap_or_default();
    let candidates = [
        std::env::var("LGDM_PYTHON").ok(),
        Some(format!("{home}/.cache/lgdm/venv/bin/python")),
        Some("python3".to_string()),
    ];
    candidates.into_iter().flatten().find(|py| {
        Command::new(py)
            .args(["-c", "import numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

#[test]
fn features_cover_every_view_and_numpy_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = DatasetSpec::small(2);
    spec.categories = vec!["bowl".into(), "book".into(), "apple".into()];
    spec.instances_per_category = 2;
    spec.collections = standard_collections().into_iter().skip(10).collect();
    spec.frames_per_sequence = 4;
    spec.grasp_images = 0;
    spec.previews = false;
    let manifest = generate(&spec, dir.path(), &mut |_| {}).unwrap();
    let ds = Dataset::open(dir.path()).unwrap();
    let mut last = None;
    let table = good_features(&ds, 15, &mut |p| last = Some((p.done, p.total))).unwrap();
    assert_eq!(last, Some((manifest.views, manifest.views)));
    assert_eq!(table.dim, 675);
    assert_eq!(table.len() as u64, manifest.views);
    for i in 0..table.len() {
        let row = table.row(i);
        for block in row.chunks(225) {
            assert!((block.iter().sum::<f32>() - 1.0).abs() < 1e-4);
        }
        assert_eq!(
            table.category[i],
            manifest.instances[table.instance[i] as usize].category
        );
        assert_eq!(
            table.sequence[i],
            manifest.sequence_id(table.collection[i], table.instance[i])
        );
    }
    // Rows are in collection, sequence, frame order.
    assert!(table.sequence.windows(2).all(|w| w[0] <= w[1]));
    let path = dir.path().join("features.npz");
    table.write_npz(&path).unwrap();
    assert_eq!(FeatureTable::read_npz(&path).unwrap(), table);

    let Some(py) = python_with_numpy() else {
        eprintln!("skipping the numpy check: no Python with numpy found");
        return;
    };
    let script = format!(
        "import numpy as np\nz = np.load(r'{}')\n\
         assert sorted(z.files) == sorted(['features','collection','category','instance','sequence','frame']), z.files\n\
         f = z['features']\nassert f.dtype == np.float32 and f.shape == ({}, 675), (f.dtype, f.shape)\n\
         assert z['sequence'].dtype == np.uint64 and z['frame'].dtype == np.uint32\n\
         assert np.allclose(f.reshape(-1, 3, 225).sum(-1), 1.0, atol=1e-4)\n\
         print(float(f[0, :5].sum()), int(z['instance'][-1]))\n",
        path.display(),
        table.len()
    );
    let out = Command::new(&py).args(["-c", &script]).output().unwrap();
    assert!(
        out.status.success(),
        "numpy failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout);
    let mut it = printed.split_whitespace();
    let s: f32 = it.next().unwrap().parse().unwrap();
    let inst: u32 = it.next().unwrap().parse().unwrap();
    assert!((s - table.row(0)[..5].iter().sum::<f32>()).abs() < 1e-6);
    assert_eq!(inst, *table.instance.last().unwrap());
}
