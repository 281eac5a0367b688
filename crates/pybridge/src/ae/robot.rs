//! The grasp autoencoder in the robot (cargo feature `ae`): as a [`GraspSource`] for
//! `lgdm sim grasp|pick-place --grasp network` ([`NetworkSource`]), and as the recognition's
//! [`ViewEncoder`] for `lgdm sim pick-place --encoder ae` ([`AeViewEncoder`]: each view through
//! [`view_features`], the pipeline `lgdm features --encoder ae` runs on a dataset's views, so a
//! model `lgdm train --encoder ae` made recognises the robot's objects).
//!
//! The grasp source: [`NetworkSource`] loads the checkpoint once per run
//! (`lgdm_pybridge::ae::AutoEncoder`: embedded Python, the venv's numpy, torch and train_ae)
//! and answers each object-centred crop with `AutoEncoder::crop_grasps` — the crop resized to
//! the model's input, one inference, the quality / angle / width maps decoded by the Rust
//! decoder with the checkpoint's jaw, the grasps moved back to crop pixels — so they carry the
//! conventions of the analytic source (crop pixels, best first, at most k).
//!
//! It lives in the bridge, behind the `ae` feature: `lgdm-sim` (the traits) never needs torch,
//! and any library or Python caller can run network grasps. The work itself is in
//! [`super::grasps`]; these adapters keep the bridge's errors as the sources of the sim's
//! ([`SourceError::Failed`], [`lgdm_sim::recognition::error::RecognitionError::Encoder`]).
//!
//! ```ignore
//! let mut source = NetworkSource::load(&checkpoint)?; // once per run
//! let grasps = source.grasps(&query, 3)?;             // per crop
//! ```

use std::path::{Path, PathBuf};

use super::views::table_frame;
use super::{AeError, AutoEncoder, FEATURE_DIM, view_features};
use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::render::{Camera, RgbdFrame};
use lgdm_sim::grasping::source::{GraspQuery, GraspSource, ProposalCheck, SourceError};
use lgdm_sim::recognition::encoder::{EncoderError, ViewEncoder};

/// The grasp autoencoder behind [`GraspSource`] (`network`).
#[derive(Debug)]
pub struct NetworkSource {
    model: AutoEncoder,
    checkpoint: PathBuf,
}

impl NetworkSource {
    /// The source's name, as `--grasp` spells it.
    pub const NAME: &'static str = "network";

    /// Loads `checkpoint` (starts the embedded interpreter, imports numpy, torch and
    /// `train_ae.bridge` from the venv); errors name what is missing and where it looked.
    pub fn load(checkpoint: &Path) -> Result<NetworkSource, AeError> {
        Ok(NetworkSource {
            model: AutoEncoder::load(checkpoint)?,
            checkpoint: checkpoint.to_path_buf(),
        })
    }
}

impl GraspSource for NetworkSource {
    fn name(&self) -> &str {
        Self::NAME
    }

    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        self.model
            .crop_grasps_with(query.crop, query.decode, k)
            .map_err(|e| match e {
                AeError::Input(message) => SourceError::BadCrop(message),
                other => SourceError::Failed {
                    source_name: Self::NAME.into(),
                    source: Box::new(other),
                },
            })
    }

    /// `refine-first`: each proposal is checked against the close-up's depth and refined in its
    /// neighbourhood; the refused ones follow, as proposed (`docs/DESIGN.md` §5; `--proposal-check
    /// contacts` tries the network's grasps as they come).
    fn proposal_check(&self) -> ProposalCheck {
        ProposalCheck::RefineFirst
    }

    /// The checkpoint, the input side and the jaw (also printed when the run starts).
    fn describe(&self) -> String {
        let jaw = match self.model.jaw_side_fraction() {
            Some(j) => format!("jaw {j:.4} of the side"),
            None => "jaw = opening / 2".into(),
        };
        format!(
            "grasp network: {} ({} px input, {jaw})",
            self.checkpoint.display(),
            self.model.input_size()
        )
    }
}

/// The autoencoder's 256-d feature of each view, for the robot's recognition.
#[derive(Debug)]
pub struct AeViewEncoder {
    model: AutoEncoder,
    /// The table as the views' camera sees it (the background each view is drawn over).
    table: Option<(Camera, RgbdFrame)>,
}

impl AeViewEncoder {
    /// The encoder's name, as `--encoder` spells it and `lgdm train` records it.
    pub const NAME: &'static str = "ae";

    /// Loads `checkpoint` (see [`NetworkSource::load`]).
    pub fn load(checkpoint: &Path) -> Result<AeViewEncoder, AeError> {
        Ok(AeViewEncoder {
            model: AutoEncoder::load(checkpoint)?,
            table: None,
        })
    }
}

impl ViewEncoder for AeViewEncoder {
    fn name(&self) -> &str {
        Self::NAME
    }

    fn dim(&self) -> usize {
        FEATURE_DIM
    }

    fn encode(
        &mut self,
        views: &[PointCloud],
        camera: &Camera,
    ) -> Result<Vec<Option<Vec<f32>>>, EncoderError> {
        if views.is_empty() {
            return Ok(Vec::new());
        }
        if self.table.as_ref().is_none_or(|(c, _)| c != camera) {
            self.table = Some((*camera, table_frame(camera)));
        }
        let (_, table) = self.table.as_ref().expect("set above");
        view_features(&self.model, views, camera, table)
            .map(|rows| rows.into_iter().map(Some).collect())
            .map_err(|e| Box::new(e) as EncoderError)
    }
}
