//! The Rust side of the autoencoder bridge returns exactly what `train_ae.bridge.infer` returns
//! in Python, for a freshly initialised `cpu`-configuration checkpoint, with the documented
//! shapes and L2-normalised features. Needs `--features ae` and numpy, torch and train_ae in the
//! venv (`$VIRTUAL_ENV`, `$LGDM_VENV` or ~/.cache/lgdm/venv); a missing one fails with its name.
#![cfg(feature = "ae")]

use lgdm_pybridge::ae::{self, AeError, AutoEncoder, FEATURE_DIM};
use numpy::ndarray::Array4;
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Writes a seeded, untrained `cpu`-config checkpoint with train_ae's own writer.
fn write_checkpoint(path: &std::path::Path) {
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
}

#[test]
fn infer_matches_python_and_has_the_documented_shapes() {
    let dir = std::env::temp_dir().join(format!("lgdm-ae-bridge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ckpt = dir.join("ae.pt");
    write_checkpoint(&ckpt);
    let model = AutoEncoder::load(&ckpt).unwrap_or_else(|e| panic!("{e}"));
    let s = model.input_size();
    assert_eq!(s, 112, "the cpu configuration works at 112×112");

    // Two images: a preprocessed synthetic RGB-D image and a smooth ramp.
    let rgb: Vec<u8> = (0..s * s * 3).map(|i| (i * 7 % 251) as u8).collect();
    let depth: Vec<f32> = (0..s * s).map(|i| 0.6 + 0.001 * (i % s) as f32).collect();
    let mut rgbd = model.preprocess(&rgb, &depth, s, s).unwrap();
    assert_eq!(rgbd.len(), 4 * s * s);
    rgbd.extend((0..4 * s * s).map(|i| ((i % 97) as f32 / 97.0) - 0.5));
    let out = model.infer(&rgbd, 2, s, s).unwrap();
    assert_eq!((out.n, out.h, out.w), (2, s, s));
    assert_eq!(out.features.len(), 2 * FEATURE_DIM);
    for maps in [&out.quality, &out.cos2t, &out.sin2t, &out.width] {
        assert_eq!(maps.len(), 2 * s * s);
        assert!(maps.iter().all(|v| v.is_finite()));
    }
    for i in 0..2 {
        let norm: f32 = out.feature(i).iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((norm - 1.0).abs() < 1e-4, "feature {i} has norm {norm}");
    }
    assert_ne!(out.feature(0), out.feature(1));

    // The same call made directly in Python gives the same numbers.
    let expected: Vec<Vec<f32>> = Python::attach(|py| {
        let bridge = py.import("train_ae.bridge").unwrap();
        let m = bridge
            .call_method1("load", (ckpt.to_string_lossy().into_owned(),))
            .unwrap();
        let x = Array4::from_shape_vec((2, 4, s, s), rgbd.clone())
            .unwrap()
            .into_pyarray(py);
        let parts: Vec<Bound<'_, PyAny>> = bridge
            .call_method1("infer", (m, x))
            .unwrap()
            .extract()
            .unwrap();
        parts
            .iter()
            .map(|p| {
                let a = p.cast::<PyArrayDyn<f32>>().unwrap().readonly();
                a.as_array().iter().copied().collect()
            })
            .collect()
    });
    assert_eq!(expected[0], out.features);
    assert_eq!(expected[1], out.quality);
    assert_eq!(expected[4], out.width);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_and_missing_checkpoint_are_typed_errors() {
    let dir = std::env::temp_dir().join(format!("lgdm-ae-missing-{}", std::process::id()));
    let err = AutoEncoder::load(&dir.join("nope.pt")).unwrap_err();
    assert!(matches!(err, AeError::Checkpoint { .. }), "{err}");
    assert!(err.to_string().contains("nope.pt"));

    let ckpt = dir.join("ae.pt");
    std::fs::create_dir_all(&dir).unwrap();
    write_checkpoint(&ckpt);
    let model = AutoEncoder::load(&ckpt).unwrap();
    let s = model.input_size();
    assert!(matches!(
        model.infer(&[0.0; 10], 1, s, s),
        Err(AeError::Input(_))
    ));
    assert!(matches!(model.infer(&[], 0, s, s), Err(AeError::Input(_))));
    let mut nan = vec![0.0; 4 * s * s];
    nan[5] = f32::NAN;
    assert!(matches!(model.infer(&nan, 1, s, s), Err(AeError::Input(_))));
    assert!(matches!(
        model.preprocess(&[0; 3], &[0.5], s, s),
        Err(AeError::Input(_))
    ));
    std::fs::remove_dir_all(&dir).ok();
}
