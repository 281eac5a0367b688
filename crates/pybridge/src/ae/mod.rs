//! The embedding side of the bridge (cargo feature `ae`): Rust calls the torch grasp
//! autoencoder of `python/train_ae` through an embedded Python interpreter, for 256-d object
//! features and pixel-wise grasp maps.
//!
//! The Python side is `train_ae.bridge` (`load`, `input_size`, `preprocess`, `infer`); it needs
//! numpy and torch. The embedded interpreter sees a virtual environment's packages only when
//! told where it is: [`AutoEncoder::load`] adds the site-packages of `$VIRTUAL_ENV`, else
//! `$LGDM_VENV`, else `~/.cache/lgdm/venv` (the venv `tests/run-all.sh` sets up), including its
//! `.pth` files (editable installs). When an import fails, the error names what is missing
//! and where it looked ([`AeError::Missing`]).
//!
//! [`views`] turns point-cloud views into the network's input and a dataset into a feature
//! table (`--encoder ae`); [`grasps`] turns an object-centred crop into ranked grasps in crop
//! pixels (the robot's `--grasp network`).
//!
//! ```no_run
//! use lgdm_pybridge::ae::AutoEncoder;
//! let ae = AutoEncoder::load("runs/ae/ae.pt".as_ref())?;
//! let s = ae.input_size();
//! let rgbd = vec![0.0f32; 4 * s * s]; // one preprocessed image (see AutoEncoder::preprocess)
//! let out = ae.infer(&rgbd, 1, s, s)?;
//! assert_eq!(out.features.len(), 256);
//! # Ok::<(), lgdm_pybridge::ae::AeError>(())
//! ```

use std::path::{Path, PathBuf};

use numpy::ndarray::{Array3, Array4};
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyModule;

pub mod grasps;
pub mod robot;
pub mod views;

pub use crate::decode::{crop_from_input, decode_params};
pub use views::{
    AE_BATCH, FeatureStats, PIPELINE, ViewImage, dataset_features, view_features, view_image,
};

/// Length of the autoencoder's feature vector.
pub const FEATURE_DIM: usize = 256;

/// Errors of the autoencoder bridge.
#[derive(Debug, thiserror::Error)]
pub enum AeError {
    /// A Python module could not be imported.
    #[error(
        "the autoencoder backend needs the Python module `{module}`, which could not be \
         imported ({reason}); {hint}"
    )]
    Missing {
        /// The module (`numpy`, `torch`, `train_ae.bridge`).
        module: String,
        /// The Python error.
        reason: String,
        /// Where it looked and what to do.
        hint: String,
    },
    /// The checkpoint could not be loaded.
    #[error("loading the autoencoder checkpoint {}: {reason}", path.display())]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// The Python error.
        reason: String,
    },
    /// Bad input to [`AutoEncoder::infer`] or [`AutoEncoder::preprocess`].
    #[error("autoencoder input: {0}")]
    Input(String),
    /// Python raised during inference, or returned something unexpected.
    #[error("autoencoder inference: {0}")]
    Python(String),
    /// Decoding the network's grasp maps failed (bad parameters or non-finite maps).
    #[error("decoding the grasp maps: {0}")]
    Decode(#[from] lgdm_pointcloud::grasp::decode::GraspDecodeError),
    /// `train_ae.bridge.default_checkpoint()` is missing or names no file.
    #[error("no default autoencoder checkpoint: {0}")]
    NoDefaultCheckpoint(String),
    /// The dataset could not be read.
    #[error("reading the dataset: {0}")]
    Dataset(String),
}

/// Output of [`AutoEncoder::infer`] for n images of h × w pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct AeOutput {
    /// Images.
    pub n: usize,
    /// Rows per map.
    pub h: usize,
    /// Columns per map.
    pub w: usize,
    /// n × [`FEATURE_DIM`] L2-normalised features, row-major.
    pub features: Vec<f32>,
    /// Grasp quality per pixel, n × h × w.
    pub quality: Vec<f32>,
    /// cos 2θ per pixel, n × h × w.
    pub cos2t: Vec<f32>,
    /// sin 2θ per pixel, n × h × w.
    pub sin2t: Vec<f32>,
    /// Gripper opening per pixel (pixels / `train_ae.bridge.WIDTH_SCALE_PX`), n × h × w.
    pub width: Vec<f32>,
}

impl AeOutput {
    /// The feature vector of image `i`.
    pub fn feature(&self, i: usize) -> &[f32] {
        &self.features[i * FEATURE_DIM..(i + 1) * FEATURE_DIM]
    }
}

/// The virtual environment the embedded interpreter should use: `$VIRTUAL_ENV`, else
/// `$LGDM_VENV`, else `~/.cache/lgdm/venv`; `None` if none is set or exists.
pub fn venv_dir() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("VIRTUAL_ENV").map(PathBuf::from),
        std::env::var_os("LGDM_VENV").map(PathBuf::from),
        std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/lgdm/venv")),
    ];
    candidates.into_iter().flatten().find(|p| p.is_dir())
}

fn hint(venv: Option<&Path>, module: &str) -> String {
    let what = match module {
        "torch" => "torch (`pip install torch`)",
        "numpy" => "numpy (`pip install numpy`)",
        _ => "python/train_ae (`pip install -e python/train_ae`)",
    };
    match venv {
        Some(v) => format!(
            "looked in the venv {} (from $VIRTUAL_ENV, $LGDM_VENV or ~/.cache/lgdm/venv): install \
             {what} there, or point LGDM_VENV at a venv that has it",
            v.display()
        ),
        None => format!(
            "no venv found ($VIRTUAL_ENV, $LGDM_VENV and ~/.cache/lgdm/venv are unset or \
             missing): create one with {what} and set LGDM_VENV to it"
        ),
    }
}

/// Adds the venv's site-packages (with its `.pth` files) to the embedded interpreter's path.
fn add_venv(py: Python<'_>, venv: &Path) -> PyResult<()> {
    let sys = py.import("sys")?;
    let (major, minor): (u32, u32) = (
        sys.getattr("version_info")?.getattr("major")?.extract()?,
        sys.getattr("version_info")?.getattr("minor")?.extract()?,
    );
    for lib in ["lib", "lib64"] {
        let site = venv
            .join(lib)
            .join(format!("python{major}.{minor}"))
            .join("site-packages");
        if site.is_dir() {
            py.import("site")?
                .call_method1("addsitedir", (site.to_string_lossy().into_owned(),))?;
        }
    }
    Ok(())
}

/// Makes the venv's packages importable in the attached interpreter and imports
/// numpy, torch and `train_ae.bridge`; returns the bridge module. Errors name what is missing.
pub fn prepare(py: Python<'_>) -> Result<Bound<'_, PyModule>, AeError> {
    let venv = venv_dir();
    if let Some(v) = &venv {
        add_venv(py, v).map_err(|e| AeError::Missing {
            module: "site".into(),
            reason: e.to_string(),
            hint: hint(Some(v), "train_ae"),
        })?;
    }
    let mut bridge = None;
    for module in ["numpy", "torch", "train_ae.bridge"] {
        let m = py.import(module).map_err(|e| AeError::Missing {
            module: module.into(),
            reason: e.to_string(),
            hint: hint(venv.as_deref(), module),
        })?;
        bridge = Some(m);
    }
    Ok(bridge.expect("imported"))
}

/// The shipped default checkpoint: the path `train_ae.bridge.default_checkpoint()` returns
/// (`weights/cpu.pt` in the train_ae package). Starts the interpreter and imports numpy, torch
/// and `train_ae.bridge` like [`AutoEncoder::load`]; [`AeError::NoDefaultCheckpoint`] when this
/// train_ae has no such function or the file is absent.
pub fn default_checkpoint() -> Result<PathBuf, AeError> {
    Python::initialize();
    Python::attach(|py| {
        let bridge = prepare(py)?;
        if !bridge.hasattr("default_checkpoint").unwrap_or(false) {
            return Err(AeError::NoDefaultCheckpoint(format!(
                "the installed train_ae ({}) has no `bridge.default_checkpoint()`: it predates \
                 the shipped weights; update it (`pip install -e python/train_ae`)",
                module_file(&bridge)
            )));
        }
        let path: PathBuf = bridge
            .call_method0("default_checkpoint")
            .and_then(|p| p.extract::<String>())
            .map(PathBuf::from)
            .map_err(|e| AeError::NoDefaultCheckpoint(e.to_string()))?;
        if !path.is_file() {
            return Err(AeError::NoDefaultCheckpoint(format!(
                "`train_ae.bridge.default_checkpoint()` names {}, which is not a file",
                path.display()
            )));
        }
        Ok(path)
    })
}

/// Where a module was imported from, for messages.
fn module_file(m: &Bound<'_, PyModule>) -> String {
    m.getattr("__file__")
        .and_then(|f| f.extract::<String>())
        .unwrap_or_else(|_| "location unknown".into())
}

/// A loaded autoencoder (model in eval mode on the CPU) and the bridge module.
#[derive(Debug)]
pub struct AutoEncoder {
    bridge: Py<PyModule>,
    model: Py<PyAny>,
    input_size: usize,
    jaw_side_fraction: Option<f32>,
}

impl AutoEncoder {
    /// Starts (or joins) the Python interpreter, makes the venv's packages importable, imports
    /// numpy, torch and `train_ae.bridge`, and loads a checkpoint written by
    /// `python -m train_ae.train`.
    pub fn load(checkpoint: &Path) -> Result<AutoEncoder, AeError> {
        Python::initialize();
        Python::attach(|py| {
            let bridge = prepare(py)?;
            if !checkpoint.is_file() {
                return Err(AeError::Checkpoint {
                    path: checkpoint.to_path_buf(),
                    reason: "no such file".into(),
                });
            }
            let ckpt_err = |e: PyErr| AeError::Checkpoint {
                path: checkpoint.to_path_buf(),
                reason: e.to_string(),
            };
            let model = bridge
                .call_method1("load", (checkpoint.to_string_lossy().into_owned(),))
                .map_err(ckpt_err)?;
            let input_size: usize = bridge
                .call_method1("input_size", (&model,))
                .and_then(|s| s.extract())
                .map_err(ckpt_err)?;
            if !bridge.hasattr("jaw_side_fraction").unwrap_or(false) {
                return Err(AeError::Checkpoint {
                    path: checkpoint.to_path_buf(),
                    reason: format!(
                        "the installed train_ae ({}) has no `bridge.jaw_side_fraction()`: it \
                         predates decoding with the gripper's jaw; update it (`pip install -e \
                         python/train_ae`)",
                        module_file(&bridge)
                    ),
                });
            }
            let jaw_side_fraction: Option<f32> = bridge
                .call_method1("jaw_side_fraction", (&model,))
                .and_then(|j| j.extract())
                .map_err(ckpt_err)?;
            if jaw_side_fraction.is_some_and(|j| !(j.is_finite() && j > 0.0 && j <= 1.0)) {
                return Err(AeError::Checkpoint {
                    path: checkpoint.to_path_buf(),
                    reason: format!("its jaw_side_fraction {jaw_side_fraction:?} is not in (0, 1]"),
                });
            }
            Ok(AutoEncoder {
                bridge: bridge.unbind(),
                model: model.unbind(),
                input_size,
                jaw_side_fraction,
            })
        })
    }

    /// The square side (pixels) the model was trained at; render or project to it.
    pub fn input_size(&self) -> usize {
        self.input_size
    }

    /// The decoded jaw as a fraction of the map side, from the checkpoint's config
    /// (`train_ae.bridge.jaw_side_fraction`: the training data's finger width over its crop
    /// side); `None`: half the opening (Cornell's convention, older checkpoints).
    pub fn jaw_side_fraction(&self) -> Option<f32> {
        self.jaw_side_fraction
    }

    /// The network input of one image (`train_ae.bridge.preprocess`): `rgb` h × w × 3 bytes and
    /// `depth_m` h × w metres (a square crop, e.g. 224 px) → resized to the input size `s` with
    /// training's resize, normalised → 4 × s × s floats (depth, R, G, B planes).
    pub fn preprocess(
        &self,
        rgb: &[u8],
        depth_m: &[f32],
        h: usize,
        w: usize,
    ) -> Result<Vec<f32>, AeError> {
        if rgb.len() != h * w * 3 || depth_m.len() != h * w {
            return Err(AeError::Input(format!(
                "preprocess of a {h} × {w} image needs {} RGB bytes and {} depths, got {} and {}",
                h * w * 3,
                h * w,
                rgb.len(),
                depth_m.len()
            )));
        }
        Python::attach(|py| {
            let rgb = Array3::from_shape_vec((h, w, 3), rgb.to_vec())
                .expect("checked length")
                .into_pyarray(py);
            let depth = numpy::ndarray::Array2::from_shape_vec((h, w), depth_m.to_vec())
                .expect("checked length")
                .into_pyarray(py);
            let out = self
                .bridge
                .bind(py)
                .call_method1("preprocess", (rgb, depth, self.input_size))
                .map_err(|e| AeError::Input(e.to_string()))?;
            let s = self.input_size;
            floats(&out, &[4, s, s], "preprocess")
        })
    }

    /// Runs the model on `n` preprocessed images (`rgbd`: n × 4 × h × w floats, row-major):
    /// features and grasp maps. The GIL is held by this thread; torch releases it while it
    /// computes.
    pub fn infer(&self, rgbd: &[f32], n: usize, h: usize, w: usize) -> Result<AeOutput, AeError> {
        if n == 0 || h == 0 || w == 0 {
            return Err(AeError::Input(format!(
                "empty batch: n = {n}, h = {h}, w = {w}"
            )));
        }
        if rgbd.len() != n * 4 * h * w {
            return Err(AeError::Input(format!(
                "{n} images of 4 × {h} × {w} need {} floats, got {}",
                n * 4 * h * w,
                rgbd.len()
            )));
        }
        if let Some(i) = rgbd.iter().position(|v| !v.is_finite()) {
            return Err(AeError::Input(format!(
                "value {i} (image {}) is not finite",
                i / (4 * h * w)
            )));
        }
        Python::attach(|py| {
            let x = Array4::from_shape_vec((n, 4, h, w), rgbd.to_vec())
                .expect("checked length")
                .into_pyarray(py);
            let out = self
                .bridge
                .bind(py)
                .call_method1("infer", (self.model.bind(py), x))
                .map_err(|e| AeError::Python(e.to_string()))?;
            let parts: Vec<Bound<'_, PyAny>> = out
                .extract()
                .map_err(|e| AeError::Python(format!("infer returned no tuple: {e}")))?;
            if parts.len() != 5 {
                return Err(AeError::Python(format!(
                    "infer returned {} values, expected 5 (features, quality, cos2t, sin2t, width)",
                    parts.len()
                )));
            }
            let map = |i: usize, name: &str| floats(&parts[i], &[n, h, w], name);
            Ok(AeOutput {
                n,
                h,
                w,
                features: floats(&parts[0], &[n, FEATURE_DIM], "features")?,
                quality: map(1, "quality")?,
                cos2t: map(2, "cos2t")?,
                sin2t: map(3, "sin2t")?,
                width: map(4, "width")?,
            })
        })
    }
}

/// The values of a float32 numpy array of the expected shape, in row-major order.
fn floats(obj: &Bound<'_, PyAny>, shape: &[usize], name: &str) -> Result<Vec<f32>, AeError> {
    let arr = obj
        .cast::<PyArrayDyn<f32>>()
        .map_err(|_| AeError::Python(format!("{name} is not a float32 numpy array")))?;
    if arr.shape() != shape {
        return Err(AeError::Python(format!(
            "{name} has shape {:?}, expected {shape:?}",
            arr.shape()
        )));
    }
    let ro = arr.readonly();
    Ok(ro.as_array().iter().copied().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_module_errors_say_what_and_where() {
        let e = AeError::Missing {
            module: "torch".into(),
            reason: "ModuleNotFoundError: No module named 'torch'".into(),
            hint: hint(Some(Path::new("/v")), "torch"),
        };
        let text = e.to_string();
        assert!(text.contains("`torch`"), "{text}");
        assert!(text.contains("/v"), "{text}");
        assert!(text.contains("pip install torch"), "{text}");
        assert!(hint(None, "train_ae.bridge").contains("LGDM_VENV"));
        assert!(hint(None, "train_ae.bridge").contains("python/train_ae"));
    }
}
