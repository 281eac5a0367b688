//! GOOD features of a generated dataset: one 675-value row per view with its labels, written
//! as `.npz` that reads back identically here and that numpy loads. The numpy check always runs:
//! the Python is `LGDM_PYTHON`, else the project venv (`$LGDM_VENV`, else
//! `~/.cache/lgdm/venv`; `tests/run-all.sh` creates it with numpy before `cargo test`), else
//! `python3`; none with numpy is a failure that says how to get one.

use std::process::Command;

use lgdm_pointcloud::dataset::{Dataset, DatasetSpec, generate, standard_collections};
use lgdm_pointcloud::features::{FeatureTable, good_features};

/// A Python that imports numpy, or a panic listing what was tried.
fn python_with_numpy() -> String {
    let venv = std::env::var("LGDM_VENV").ok().or_else(|| {
        std::env::var("HOME")
            .ok()
            .map(|home| format!("{home}/.cache/lgdm/venv"))
    });
    let candidates: Vec<String> = [
        std::env::var("LGDM_PYTHON").ok(),
        venv.map(|v| format!("{v}/bin/python")),
        Some("python3".to_string()),
    ]
    .into_iter()
    .flatten()
    .collect();
    let mut tried = Vec::new();
    for py in &candidates {
        match Command::new(py).args(["-c", "import numpy"]).output() {
            Ok(o) if o.status.success() => return py.clone(),
            Ok(o) => tried.push(format!(
                "{py}: {}",
                String::from_utf8_lossy(&o.stderr)
                    .trim()
                    .lines()
                    .last()
                    .unwrap_or("failed")
            )),
            Err(e) => tried.push(format!("{py}: {e}")),
        }
    }
    panic!(
        "no Python with numpy to check the .npz with; tried:\n  {}\n\
         Run tests/run-all.sh (it creates the venv with numpy before `cargo test`), or create \
         one (`python3 -m venv ~/.cache/lgdm/venv && ~/.cache/lgdm/venv/bin/pip install numpy`), \
         or point LGDM_PYTHON at a Python with numpy (LGDM_VENV at a venv with it).",
        tried.join("\n  ")
    );
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

    let py = python_with_numpy();
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
