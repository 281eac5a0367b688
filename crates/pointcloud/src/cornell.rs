//! Grasp-labelled RGB-D images in the Cornell layout.

use std::path::Path;

use crate::dataset::{DatasetError, DatasetSpec, GraspSetInfo, InstanceInfo};
use crate::objects::ObjectModel;
use crate::progress::Progress;

/// Exports `spec.grasp_images` grasp-labelled images (none yet).
pub fn export_grasp_set(
    _spec: &DatasetSpec,
    _objects: &[ObjectModel],
    _instances: &[InstanceInfo],
    _out_dir: &Path,
    _progress: &mut dyn FnMut(Progress),
) -> Result<Option<GraspSetInfo>, DatasetError> {
    Ok(None)
}
