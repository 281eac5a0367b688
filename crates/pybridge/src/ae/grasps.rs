//! The autoencoder as a grasp proposer: one object-centred crop ([`ObjectCrop`], 224 px of
//! 0.22 m of table by default, the crop every grasp image of `lgdm gen-dataset` is) →
//! `train_ae.bridge.preprocess` at the model's input size (the training resize, e.g. 224 → 112
//! by area averaging) → `infer` → the quality, cos 2θ, sin 2θ and width maps decoded by the
//! Rust decoder ([`decode_grasps`], train_ae's `decode_grasps` step for step) with the
//! checkpoint's jaw ([`AutoEncoder::jaw_side_fraction`]) → the grasps moved from input pixels
//! back to crop pixels ([`crop_from_input`]: pixel-centre aligned, lengths × crop/input side,
//! angle and quality unchanged).
//!
//! The result has the conventions of `lgdm_pointcloud::grasp::analytic` (crop pixels, best
//! first, at most k), so the robot places either the same way. `python -m train_ae.evaluate`
//! decodes the same maps with the same parameters (top-1, threshold 0.2, peaks 20 px apart at
//! the input resolution, jaw = `jaw_side_fraction` × input side): the two score the same crop
//! alike (`tests/ae_bridge.rs` checks it).
//!
//! ```no_run
//! use lgdm_pybridge::ae::{AutoEncoder, default_checkpoint};
//! # fn crop() -> lgdm_pointcloud::crop::ObjectCrop { unimplemented!() }
//! let ae = AutoEncoder::load(&default_checkpoint()?)?;
//! let grasps = ae.crop_grasps(&crop(), 3)?; // crop pixels, best first
//! assert!(grasps.len() <= 3);
//! # Ok::<(), lgdm_pybridge::ae::AeError>(())
//! ```

use lgdm_pointcloud::crop::ObjectCrop;
use lgdm_pointcloud::grasp::decode::{
    DecodedGrasp, GraspDecodeParams, GraspMapsView, decode_grasps,
};

use super::{AeError, AutoEncoder};
use crate::decode::{crop_from_input, decode_params};

impl AutoEncoder {
    /// The decoder parameters of this checkpoint for at most `k` grasps ([`decode_params`] with
    /// [`AutoEncoder::jaw_side_fraction`]).
    pub fn decode_params(&self, k: usize) -> GraspDecodeParams {
        decode_params(self.jaw_side_fraction(), k)
    }

    /// At most `k` grasps on `crop`, best first, in crop pixels (see the module docs), decoded
    /// with train_ae's defaults ([`AutoEncoder::decode_params`]); an empty list when no peak of
    /// the quality map reaches the threshold or `k` is 0. Errors: a malformed crop
    /// ([`AeError::Input`]), Python ([`AeError::Python`]), non-finite maps
    /// ([`AeError::Decode`]).
    pub fn crop_grasps(&self, crop: &ObjectCrop, k: usize) -> Result<Vec<DecodedGrasp>, AeError> {
        self.crop_grasps_with(crop, &self.decode_params(k), k)
    }

    /// [`AutoEncoder::crop_grasps`] with `params`' threshold, peak distance and smoothing (e.g.
    /// a robot run's `[attempt.decode]`); the jaw is still this checkpoint's and the count `k`.
    pub fn crop_grasps_with(
        &self,
        crop: &ObjectCrop,
        params: &GraspDecodeParams,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, AeError> {
        let n = crop.size_px as usize;
        if n == 0 || crop.rgb.len() != n * n || crop.depth_m.len() != n * n {
            return Err(AeError::Input(format!(
                "a {n} × {n} px crop needs {} colours and depths, got {} and {}",
                n * n,
                crop.rgb.len(),
                crop.depth_m.len()
            )));
        }
        if k == 0 {
            return Ok(Vec::new());
        }
        let s = self.input_size();
        let x = self.preprocess(crop.rgb.as_flattened(), &crop.depth_m, n, n)?;
        let out = self.infer(&x, 1, s, s)?;
        let maps = GraspMapsView {
            rows: s,
            cols: s,
            quality: &out.quality,
            cos2t: &out.cos2t,
            sin2t: &out.sin2t,
            width: &out.width,
        };
        let params = GraspDecodeParams {
            jaw_side_fraction: self.jaw_side_fraction(),
            num_grasps: k,
            ..*params
        };
        Ok(decode_grasps(maps, &params)?
            .iter()
            .map(|g| crop_from_input(g, n, s))
            .collect())
    }
}
