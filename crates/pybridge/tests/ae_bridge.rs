//! The Rust side of the autoencoder bridge returns exactly what `train_ae.bridge.infer` returns in
//! Python, for a freshly initialised `cpu`-configuration checkpoint, with the documented shapes and
//! L2-normalised features; and the network's grasps on an object-centred crop
//! (`AutoEncoder::crop_grasps`, the Rust decoder) are the grasps `python -m train_ae.evaluate`'s
//! decoding gives on the same crop with the shipped checkpoint, in crop pixels. Needs `--features
//! ae` and numpy, torch and train_ae in the venv (`$VIRTUAL_ENV`, `$LGDM_VENV` or
//! ~/.cache/lgdm/venv); a missing one fails with its name.
#![cfg(feature = "ae")]

use lgdm_pointcloud::crop::{CropSpec, crop_largest_object};
use lgdm_pointcloud::grasp::GraspSpec;
use lgdm_pointcloud::grasp::cornell::grasp_scene;
use lgdm_pointcloud::grasp::decode::GraspDecodeParams;
use lgdm_pointcloud::objects::procedural_library;
use lgdm_pointcloud::segment::SegmentParams;
use lgdm_pybridge::ae::robot::NetworkSource;
use lgdm_pybridge::ae::{self, AeError, AutoEncoder, FEATURE_DIM};
use lgdm_sim::grasping::source::{GraspQuery, GraspSource};
use numpy::ndarray::{Array2, Array3, Array4};
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

/// The shipped checkpoint's grasps on a dataset-style crop (a mug under the top-down grasp
/// camera, cropped 0.22 m / 224 px around it) through the bridge and the Rust decoder equal
/// train_ae's own path: `bridge.preprocess` at the input size, `bridge.infer`, `decode_grasps`
/// with `jaw_px_for(jaw_side_fraction, side)` (as `train_ae.evaluate`), moved to crop pixels.
#[test]
fn crop_grasps_are_python_decode_in_crop_pixels() {
    let ckpt = ae::default_checkpoint().unwrap_or_else(|e| panic!("{e}"));
    let model = AutoEncoder::load(&ckpt).unwrap_or_else(|e| panic!("{e}"));
    let jaw = model
        .jaw_side_fraction()
        .expect("the shipped checkpoint decodes with the gripper's jaw");
    assert!((jaw - 0.02 / 0.22).abs() < 1e-4, "jaw_side_fraction {jaw}");
    let mug = procedural_library(&["mug"], 1, 1).unwrap().remove(0);
    let scene = grasp_scene(&GraspSpec::default(), 3, 0, &mug);
    let spec = CropSpec::default();
    let found = crop_largest_object(
        &scene.frame,
        &scene.camera.intrinsics,
        &SegmentParams::whole_components(),
        &spec,
    )
    .unwrap();
    assert!(found.object.is_some());
    let crop = found.crop;
    let n = crop.size_px as usize;
    let k = 3;
    let rust = model.crop_grasps(&crop, k).unwrap();
    assert!(
        !rust.is_empty(),
        "the shipped network finds no grasp on a mug"
    );
    assert!(rust.len() <= k);
    assert!(rust.windows(2).all(|w| w[0].quality >= w[1].quality));

    let python: Vec<(f64, f64, f64, f64, f64)> = Python::attach(|py| {
        let locals = PyDict::new(py);
        let rgb = Array3::from_shape_vec((n, n, 3), crop.rgb.as_flattened().to_vec()).unwrap();
        let depth = Array2::from_shape_vec((n, n), crop.depth_m.clone()).unwrap();
        locals.set_item("rgb", rgb.into_pyarray(py)).unwrap();
        locals.set_item("depth", depth.into_pyarray(py)).unwrap();
        locals
            .set_item("path", ckpt.to_string_lossy().into_owned())
            .unwrap();
        locals.set_item("k", k).unwrap();
        py.run(
            c"from train_ae import bridge
from train_ae.grasp import decode_grasps, jaw_px_for
m = bridge.load(path)
s = bridge.input_size(m)
_, q, c, sn, w = bridge.infer(m, bridge.preprocess(rgb, depth, s)[None])
found = decode_grasps(q[0], c[0], sn[0], w[0], num_grasps=k,
                      jaw_px=jaw_px_for(bridge.jaw_side_fraction(m), s))
f = rgb.shape[0] / s
out = [((g.center_x + 0.5) * f - 0.5, (g.center_y + 0.5) * f - 0.5, g.angle, g.width_px * f,
        g.jaw_px * f) for g in found]",
            // As globals: the comprehension must see `f`.
            Some(&locals),
            None,
        )
        .unwrap_or_else(|e| panic!("decoding in Python: {e}"));
        locals.get_item("out").unwrap().unwrap().extract().unwrap()
    });
    assert_eq!(rust.len(), python.len(), "rust {rust:?}\npython {python:?}");
    for (r, p) in rust.iter().zip(&python) {
        let close = |a: f32, b: f64, tol: f64| (f64::from(a) - b).abs() <= tol;
        assert!(
            close(r.center_px[0], p.0, 1e-3) && close(r.center_px[1], p.1, 1e-3),
            "centre: rust {r:?}, python {p:?}"
        );
        assert!(close(r.angle, p.2, 1e-4), "angle: rust {r:?}, python {p:?}");
        assert!(
            close(r.width_px, p.3, 1e-3),
            "opening: rust {r:?}, python {p:?}"
        );
        assert!(close(r.jaw_px, p.4, 1e-3), "jaw: rust {r:?}, python {p:?}");
    }
    // The jaw is the finger width in the crop: 0.02 m of 0.22 m at 224 px.
    assert!((rust[0].jaw_px - jaw * n as f32).abs() < 1e-3);
    // The best grasp's centre lies within a jaw of an object pixel of the crop.
    let limit = crop.table_depth_m - 0.005;
    let [cx, cy] = rust[0].center_px;
    let near_object = (0..n * n).any(|i| {
        let (x, y) = ((i % n) as f32, (i / n) as f32);
        let d = crop.depth_m[i];
        d > 0.0 && d < limit && (x - cx).hypot(y - cy) <= rust[0].jaw_px
    });
    assert!(
        near_object,
        "the best grasp {:?} is not on the mug",
        rust[0]
    );

    // A robot run's `[attempt.decode]` reaches the network source through the query: the
    // defaults give these grasps, a threshold above the best peak none, and the jaw stays the
    // checkpoint's whatever the parameters say.
    let source_grasps = |params: &GraspDecodeParams| {
        let mut source = NetworkSource::load(&ckpt).unwrap_or_else(|e| panic!("{e}"));
        let query = GraspQuery {
            crop: &crop,
            intrinsics: &scene.camera.intrinsics,
            gripper: &GraspSpec::default(),
            decode: params,
        };
        source.grasps(&query, k).unwrap()
    };
    assert_eq!(source_grasps(&GraspDecodeParams::default()), rust);
    let above = GraspDecodeParams {
        quality_threshold: rust[0].quality + 0.01,
        ..Default::default()
    };
    assert!(source_grasps(&above).is_empty());
    let other_jaw = GraspDecodeParams {
        jaw_side_fraction: None,
        ..Default::default()
    };
    assert_eq!(source_grasps(&other_jaw), rust);
}
