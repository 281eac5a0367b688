//! What turns the robot's views into the dual memory's input: the [`ViewEncoder`] trait and
//! [`GoodEncoder`].
//!
//! **Features: the dataset's code.** Each view goes through
//! [`lgdm_pointcloud::dataset::view_cloud`] (the object's pixels back-projected into the camera's
//! optical frame, subsampled to 2,048 points — what `lgdm gen-dataset` stores per frame) and a
//! [`ViewEncoder`]: [`GoodEncoder`] by default, [`lgdm_pointcloud::good::good_descriptor`] with
//! [`GOOD_BINS`] bins (what `lgdm features` / `train` / `eval` compute per stored frame: 675
//! values); the command line's `ae` build adds the autoencoder's (`--encoder ae`: the cloud
//! splatted over the table as the dataset's camera sees it, the object-centred crop, 256 values —
//! `lgdm features --encoder ae`'s pipeline). A model is only used with the encoder it was
//! trained with (its feature dimension is checked here, its run record by the command line).

use lgdm_pointcloud::cache::{GOOD_BINS, GOOD_DIM};
use lgdm_pointcloud::good::good_descriptor;

/// The default encoder's name: GOOD ([`GOOD_BINS`] bins, [`GOOD_DIM`] values).
pub const ENCODER: &str = "good";

/// What turns the robot's views into the dual memory's input: the dataset path's encoder, so a
/// model `lgdm train` made with it recognises the robot's objects. [`GoodEncoder`] here; the
/// autoencoder's (`--encoder ae`) lives with the torch bridge (`lgdm_pybridge::ae::robot`, feature
/// `ae`).
pub trait ViewEncoder: std::fmt::Debug {
    /// The name runs record (`lgdm train --encoder NAME`): `good`, `ae`.
    fn name(&self) -> &str;
    /// Values per feature.
    fn dim(&self) -> usize;
    /// One feature per view (a cloud in `camera`'s optical frame, as
    /// [`lgdm_pointcloud::dataset::view_cloud`] makes it and `lgdm gen-dataset` stores it; `camera`
    /// is the dataset's camera,
    /// [`CameraSpec::camera`](lgdm_pointcloud::dataset::CameraSpec::camera)); `None` for a view it
    /// cannot describe.
    fn encode(
        &mut self,
        views: &[lgdm_pointcloud::PointCloud],
        camera: &lgdm_pointcloud::render::Camera,
    ) -> Result<Vec<Option<Vec<f32>>>, EncoderError>;
}

/// The error of a [`ViewEncoder`] (the autoencoder's bridge error, or a caller's own): kept as the
/// source of [`RecognitionError::Encoder`](crate::recognition::error::RecognitionError::Encoder).
pub type EncoderError = Box<dyn std::error::Error + Send + Sync>;

/// GOOD with [`GOOD_BINS`] bins: what `lgdm features` computes per stored view.
#[derive(Debug, Clone, Copy, Default)]
pub struct GoodEncoder;

impl ViewEncoder for GoodEncoder {
    fn name(&self) -> &str {
        ENCODER
    }

    fn dim(&self) -> usize {
        GOOD_DIM
    }

    fn encode(
        &mut self,
        views: &[lgdm_pointcloud::PointCloud],
        _camera: &lgdm_pointcloud::render::Camera,
    ) -> Result<Vec<Option<Vec<f32>>>, EncoderError> {
        Ok(views
            .iter()
            .map(|cloud| good_descriptor(&cloud.points, GOOD_BINS).ok())
            .collect())
    }
}
