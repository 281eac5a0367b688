//! The autoencoder's view pipeline: a view's point cloud → the network's RGB-D input
//! ([`view_image`]: `lgdm_pointcloud::projection` at the network's input size, blank for an
//! empty view, grey for a colourless one) → `train_ae.bridge.preprocess` → inference in batches
//! ([`dataset_features`]: one 256-d L2-normalised feature per view of a dataset, rows in the
//! GOOD table's order, so scenarios, caches and `lgdm train` treat both encoders alike).
//!
//! `lgdm features/train/eval --encoder ae` and (later) the robot's recognition call this; the
//! feature cache keys on [`PIPELINE`] and the checkpoint's bytes.

use std::path::Path;

use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::Progress;
use lgdm_pointcloud::dataset::Dataset;
use lgdm_pointcloud::features::FeatureTable;
use lgdm_pointcloud::projection::{ProjectionError, ProjectionParams, project_to_image};

use super::{AeError, AutoEncoder, FEATURE_DIM};

/// Version of the view → network-input pipeline (projection parameters, empty-view and
/// colourless-view handling). Part of the feature cache key: change it when the pipeline changes.
pub const PIPELINE: &str = "ae-projection-v1 margin=0.08 splat=auto empty=blank grey=128";

/// Images per inference call.
pub const AE_BATCH: usize = 32;

/// Colour of object pixels when a view has no colours.
const GREY: u8 = 128;

/// One view as the network's input: `size`² pixels of RGB bytes and depth in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewImage {
    /// size × size × 3 bytes, row-major.
    pub rgb: Vec<u8>,
    /// size × size metres (0 where nothing was projected).
    pub depth_m: Vec<f32>,
    /// No point lay in front of the camera: the image is blank.
    pub empty: bool,
}

/// The network input of one view at `params.size`: a blank image (all zeros) when no point lies
/// in front of the camera; object pixels of a colourless cloud are grey.
pub fn view_image(cloud: &PointCloud, params: &ProjectionParams) -> Result<ViewImage, AeError> {
    let pixels = params.size * params.size;
    match project_to_image(cloud, params) {
        Ok(img) => {
            let rgb = match img.rgb {
                Some(rgb) => rgb.into_iter().flatten().collect(),
                None => img
                    .depth_m
                    .iter()
                    .flat_map(|&d| [if d > 0.0 { GREY } else { 0 }; 3])
                    .collect(),
            };
            Ok(ViewImage {
                rgb,
                depth_m: img.depth_m,
                empty: false,
            })
        }
        Err(ProjectionError::Empty) => Ok(ViewImage {
            rgb: vec![0; 3 * pixels],
            depth_m: vec![0.0; pixels],
            empty: true,
        }),
        Err(e) => Err(AeError::Input(format!("projecting a view: {e}"))),
    }
}

/// What [`dataset_features`] noticed besides the table.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FeatureStats {
    /// Views with no point in front of the camera (given blank images).
    pub empty_views: u64,
}

/// The autoencoder feature of every view of `ds` (one row per view, in the GOOD table's order:
/// collection, sequence in file order, frame), [`AE_BATCH`] images per inference call, with the
/// checkpoint at `checkpoint`. Progress: stage `infer`, views done of the manifest's total.
pub fn dataset_features(
    ds: &Dataset,
    checkpoint: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<(FeatureTable, FeatureStats), AeError> {
    let model = AutoEncoder::load(checkpoint)?;
    let size = model.input_size();
    let params = ProjectionParams {
        size,
        ..ProjectionParams::default()
    };
    let dataset_err = |e: lgdm_pointcloud::dataset::DatasetError| AeError::Dataset(e.to_string());
    let manifest = ds.manifest();
    let total = manifest.views;
    let mut table = FeatureTable::new(FEATURE_DIM);
    let mut batch: Vec<f32> = Vec::with_capacity(AE_BATCH * 4 * size * size);
    let mut pending = 0usize;
    let mut stats = FeatureStats::default();
    let mut flush = |batch: &mut Vec<f32>, pending: &mut usize, table: &mut FeatureTable| {
        if *pending == 0 {
            return Ok::<(), AeError>(());
        }
        let out = model.infer(batch, *pending, size, size)?;
        let first = table.features.len() / FEATURE_DIM;
        if let Some(i) = out.features.iter().position(|v| !v.is_finite()) {
            let row = first + i / FEATURE_DIM;
            return Err(AeError::Python(format!(
                "the feature of view {row} (collection {}, instance {}, frame {}) is not finite",
                table.collection[row], table.instance[row], table.frame[row]
            )));
        }
        table.features.extend_from_slice(&out.features);
        batch.clear();
        *pending = 0;
        progress(Progress {
            stage: "infer",
            done: table.features.len() as u64 / FEATURE_DIM as u64,
            total,
        });
        Ok(())
    };
    for c in 0..manifest.collections.len() as u32 {
        for seq in ds.sequences(c).map_err(dataset_err)? {
            let seq = seq.map_err(dataset_err)?;
            let sequence = manifest.sequence_id(seq.collection, seq.instance);
            for (f, cloud) in seq.frames.iter().enumerate() {
                let view = view_image(cloud, &params)?;
                stats.empty_views += u64::from(view.empty);
                batch.extend(model.preprocess(&view.rgb, &view.depth_m, size, size)?);
                table.collection.push(c);
                table.category.push(seq.category);
                table.instance.push(seq.instance);
                table.sequence.push(sequence);
                table.frame.push(f as u32);
                pending += 1;
                if pending == AE_BATCH {
                    flush(&mut batch, &mut pending, &mut table)?;
                }
            }
        }
    }
    flush(&mut batch, &mut pending, &mut table)?;
    table
        .check()
        .map_err(|e| AeError::Python(format!("autoencoder feature table: {e}")))?;
    if table.len() as u64 != total {
        return Err(AeError::Dataset(format!(
            "the dataset's manifest records {total} views, its collections hold {}",
            table.len()
        )));
    }
    Ok((table, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_images_have_the_input_size_and_blank_empty_views() {
        let params = ProjectionParams {
            size: 16,
            ..ProjectionParams::default()
        };
        let pts: Vec<[f32; 3]> = (0..100)
            .map(|i| [(i % 10) as f32 * 0.01, (i / 10) as f32 * 0.01, 0.8])
            .collect();
        let v = view_image(&PointCloud::new(pts.clone(), None), &params).unwrap();
        assert!(!v.empty);
        assert_eq!((v.rgb.len(), v.depth_m.len()), (3 * 256, 256));
        assert!(v.depth_m.iter().any(|&d| d > 0.0));
        for (px, &d) in v.rgb.chunks(3).zip(&v.depth_m) {
            assert_eq!(px[0], if d > 0.0 { GREY } else { 0 });
        }
        let colours = vec![[10u8, 20, 30]; pts.len()];
        let v = view_image(&PointCloud::new(pts, Some(colours)), &params).unwrap();
        assert!(v.rgb.chunks(3).any(|px| px == [10, 20, 30]));
        let behind = PointCloud::new(vec![[0.0, 0.0, -1.0]], None);
        let v = view_image(&behind, &params).unwrap();
        assert!(v.empty);
        assert!(v.rgb.iter().all(|&x| x == 0) && v.depth_m.iter().all(|&d| d == 0.0));
    }
}
