//! The grasp source and the view encoder a run's options name, loaded once for the run: the
//! built-in sources, or the grasp autoencoder's (`lgdm_pybridge::ae::robot`) in a build with the
//! `ae` feature; without it, an error saying how to get it.

use std::path::Path;

use anyhow::{Result, bail};
use lgdm_sim::grasping::source::{GraspSource, builtin_source};
use lgdm_sim::recognition::encoder::{GoodEncoder, ViewEncoder};

use super::GraspArg;
use crate::progress::Reporter;

/// Why `--grasp network` cannot run in a build without the `ae` feature, and what to do.
#[cfg_attr(feature = "ae", allow(dead_code))]
pub const NETWORK_NOT_BUILT: &str = "--grasp network needs the torch grasp autoencoder, and this \
`lgdm` binary was built without the `ae` feature (the default build neither links libpython nor \
needs torch). Rebuild it with `cargo build --release -p lgdm-cli --features ae`, and install torch \
and the autoencoder package into a venv: `python3 -m venv ~/.cache/lgdm/venv && \
~/.cache/lgdm/venv/bin/pip install -e python/train_ae` (or activate your own venv, or set \
LGDM_VENV to it); see docs/guide/grasp-network.md. Or use --grasp analytic or --grasp random";

/// The grasp source `grasp`, loaded once for the whole run. `ae_encoder`: whether recognition
/// uses the autoencoder (then `--ae-checkpoint` applies without `--grasp network`); `None` for
/// commands without recognition.
pub(super) fn source(
    grasp: GraspArg,
    ae_checkpoint: Option<&Path>,
    seed: u64,
    ae_encoder: Option<bool>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    if let (Some(p), false) = (
        ae_checkpoint,
        grasp == GraspArg::Network || ae_encoder == Some(true),
    ) {
        let also = if ae_encoder.is_some() {
            " and --encoder ae"
        } else {
            ""
        };
        bail!(
            "--ae-checkpoint {} only applies to --grasp network{also}",
            p.display()
        );
    }
    match grasp {
        GraspArg::Analytic => Ok(builtin_source("analytic", seed)?),
        GraspArg::Random => Ok(builtin_source("random", seed)?),
        GraspArg::Network => network_source(ae_checkpoint, reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn network_source(_: Option<&std::path::Path>, _: &Reporter) -> Result<Box<dyn GraspSource>> {
    bail!(NETWORK_NOT_BUILT)
}

/// The grasp autoencoder (`lgdm_pybridge::ae::robot::NetworkSource`) from `checkpoint`, else
/// the one shipped with train_ae; a missing venv, module or checkpoint is an error naming it.
#[cfg(feature = "ae")]
fn network_source(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use lgdm_pybridge::ae::robot::NetworkSource;
    const USER: &str = "--grasp network";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let source = NetworkSource::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    reporter.message(&source.describe());
    Ok(Box::new(source))
}

/// The view encoder: GOOD, or with `ae` the autoencoder (from `checkpoint`).
pub(super) fn view_encoder(
    ae: bool,
    checkpoint: Option<&Path>,
    reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    match ae {
        false => Ok(Box::new(GoodEncoder)),
        true => ae_view_encoder(checkpoint, reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn ae_view_encoder(_: Option<&std::path::Path>, _: &Reporter) -> Result<Box<dyn ViewEncoder>> {
    bail!(crate::data::ae::NOT_BUILT)
}

/// The autoencoder as recognition's encoder (`lgdm_pybridge::ae::robot::AeViewEncoder`).
#[cfg(feature = "ae")]
fn ae_view_encoder(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use lgdm_pybridge::ae::robot::AeViewEncoder;
    const USER: &str = "--encoder ae";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let encoder = AeViewEncoder::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    let from = checkpoint.display();
    reporter.message(&format!("recognition: autoencoder features from {from}"));
    Ok(Box::new(encoder))
}
