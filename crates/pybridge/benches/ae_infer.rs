//! Time per image of the autoencoder through the bridge (`AutoEncoder::infer`: numpy copy in,
//! torch forward, five arrays copied out), `cpu` configuration (112×112), batch 1 and 16, beside
//! the same `train_ae.bridge.infer` call made on a ready numpy array with no copies (`python_call`,
//! same process: the difference is the bridge's cost), and `AutoEncoder::preprocess` of one
//! 224-px object-centred crop (resize to 112 and normalisation). The standalone-Python figure: `python -m train_ae.bench --config cpu --batch-size 16`.
//! Run with `cargo bench -p lgdm-pybridge --features ae --bench ae_infer` (a venv with torch and
//! train_ae as for the `ae_bridge` test; `OMP_NUM_THREADS=1` on a loaded machine, where two
//! OpenMP threads on two busy cores make batch-1 times erratic). Criterion reports the time per
//! call; divide by the batch size.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use lgdm_pybridge::ae::{self, AutoEncoder};
use numpy::IntoPyArray;
use numpy::ndarray::Array4;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A seeded, untrained `cpu` checkpoint (timing does not depend on the weights).
fn checkpoint() -> std::path::PathBuf {
    let path = std::env::temp_dir().join(format!("lgdm-ae-bench-{}.pt", std::process::id()));
    Python::initialize();
    Python::attach(|py| {
        ae::prepare(py).unwrap_or_else(|e| panic!("{e}"));
        let locals = PyDict::new(py);
        locals
            .set_item("path", path.to_string_lossy().into_owned())
            .unwrap();
        py.run(
            c"import torch
from train_ae.model import GraspAutoencoder, ModelConfig
from train_ae.checkpoint import save_checkpoint
torch.manual_seed(0)
save_checkpoint(path, GraspAutoencoder(ModelConfig.preset('cpu')), {})",
            None,
            Some(&locals),
        )
        .unwrap_or_else(|e| panic!("writing the checkpoint: {e}"));
    });
    path
}

fn bench(c: &mut Criterion) {
    let ckpt = checkpoint();
    let model = AutoEncoder::load(&ckpt).unwrap_or_else(|e| panic!("{e}"));
    // The same checkpoint loaded on the Python side, for the no-copy baseline.
    let (bridge, py_model) = Python::attach(|py| {
        let bridge = py.import("train_ae.bridge").unwrap();
        let m = bridge
            .call_method1("load", (ckpt.to_string_lossy().into_owned(),))
            .unwrap();
        (bridge.unbind(), m.unbind())
    });
    std::fs::remove_file(&ckpt).ok();
    let s = model.input_size();
    let mut group = c.benchmark_group("ae_cpu");
    group.sample_size(20);
    for n in [1usize, 16] {
        // Deterministic values in [-0.5, 0.5): like a preprocessed image's range.
        let x: Vec<f32> = (0..n * 4 * s * s)
            .map(|i| ((i as u64).wrapping_mul(2_654_435_761) % 1000) as f32 / 1000.0 - 0.5)
            .collect();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::new("infer", n), &n, |b, &n| {
            b.iter(|| model.infer(&x, n, s, s).unwrap())
        });
        Python::attach(|py| {
            let arr = Array4::from_shape_vec((n, 4, s, s), x.clone())
                .unwrap()
                .into_pyarray(py);
            let (bridge, m) = (bridge.bind(py), py_model.bind(py));
            group.bench_with_input(BenchmarkId::new("python_call", n), &n, |b, _| {
                b.iter(|| bridge.call_method1("infer", (m, &arr)).unwrap())
            });
        });
    }
    // One object-centred crop as the robot and the datasets make it (224 px), resized to the
    // input and normalised.
    let c = lgdm_pointcloud::crop::DEFAULT_CROP_PX as usize;
    let rgb: Vec<u8> = (0..c * c * 3).map(|i| (i * 7 % 251) as u8).collect();
    let depth: Vec<f32> = (0..c * c).map(|i| 0.6 + 0.001 * (i % c) as f32).collect();
    group.throughput(Throughput::Elements(1));
    group.bench_function("preprocess_crop", |b| {
        b.iter(|| model.preprocess(&rgb, &depth, c, c).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
