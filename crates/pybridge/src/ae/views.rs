//! The autoencoder's view pipeline: a view's point cloud → the grasp network's input, the
//! object-centred crop of `lgdm_pointcloud::crop` ([`view_image`]: the cloud splatted over the
//! table as the dataset's camera sees it, segmented and cropped exactly as the grasp images
//! and the robot's camera are, so recognition sees what grasping was trained on) →
//! `train_ae.bridge.preprocess` (resized to the network's input) → inference in batches
//! ([`dataset_features`]: one 256-d L2-normalised feature per view of a dataset, rows in the
//! GOOD table's order, so scenarios, caches and `lgdm train` treat both encoders alike).
//!
//! `lgdm features/train/eval --encoder ae` and the robot's recognition call this; the feature
//! cache keys on [`PIPELINE`] and the checkpoint's bytes.

use std::path::Path;

use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::Progress;
use lgdm_pointcloud::crop::{CropSpec, crop_largest_object};
use lgdm_pointcloud::dataset::Dataset;
use lgdm_pointcloud::features::FeatureTable;
use lgdm_pointcloud::grasp::cornell::{TABLE_LABEL, table_mesh};
use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::render::{Camera, RenderItem, RgbdFrame, render, splat_cloud};
use lgdm_pointcloud::segment::SegmentParams;

use super::{AeError, AutoEncoder, FEATURE_DIM};

/// Version of the view → network-input pipeline (table, splatting, segmentation, crop).
/// Part of the feature cache key: change it when the pipeline changes.
pub const PIPELINE: &str = "ae-crop-v1 table=render splat=auto segment=default crop=0.22m/224px";

/// Images per inference call.
pub const AE_BATCH: usize = 32;

/// One view as the network sees it: the object-centred crop (RGB bytes and depth in metres).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewImage {
    /// Side, pixels.
    pub size: usize,
    /// size × size × 3 bytes, row-major.
    pub rgb: Vec<u8>,
    /// size × size metres (0 where nothing was seen).
    pub depth_m: Vec<f32>,
    /// No object stood out of the table: the crop shows the table at the frame's centre.
    pub empty: bool,
}

/// The table as `camera` sees it: the background every view is drawn over.
pub fn table_frame(camera: &Camera) -> RgbdFrame {
    let table = table_mesh();
    render(
        camera,
        &[RenderItem {
            mesh: &table,
            world_from_object: Pose::identity(),
            label: TABLE_LABEL,
        }],
    )
}

/// The network input of one view (a cloud in `camera`'s optical frame, standing on the table
/// of `table`, which is [`table_frame`]`(camera)`): the cloud splatted over the table, then
/// the object-centred crop of the largest object ([`CropSpec::default`]).
pub fn view_image(
    cloud: &PointCloud,
    camera: &Camera,
    table: &RgbdFrame,
) -> Result<ViewImage, AeError> {
    let mut frame = table.clone();
    splat_cloud(&mut frame, &camera.intrinsics, cloud, None);
    let spec = CropSpec::default();
    let found = crop_largest_object(
        &frame,
        &camera.intrinsics,
        &SegmentParams::whole_components(),
        &spec,
    )
    .map_err(|e| AeError::Input(format!("cropping a view: {e}")))?;
    Ok(ViewImage {
        size: spec.size_px as usize,
        rgb: found.crop.rgb.into_iter().flatten().collect(),
        depth_m: found.crop.depth_m,
        empty: found.object.is_none(),
    })
}

/// The features of a few views (clouds in `camera`'s optical frame, `table` =
/// [`table_frame`]`(camera)`), one row per cloud, as [`dataset_features`] computes a dataset's:
/// the robot's recognition with `--encoder ae` (a look's or a lesson's views).
pub fn view_features(
    model: &AutoEncoder,
    clouds: &[PointCloud],
    camera: &Camera,
    table: &RgbdFrame,
) -> Result<Vec<Vec<f32>>, AeError> {
    let size = model.input_size();
    let per_image = 4 * size * size;
    let mut batch = Vec::with_capacity(clouds.len() * per_image);
    for cloud in clouds {
        let view = view_image(cloud, camera, table)?;
        batch.extend(model.preprocess(&view.rgb, &view.depth_m, view.size, view.size)?);
    }
    let mut rows = Vec::with_capacity(clouds.len());
    for chunk in batch.chunks(AE_BATCH * per_image) {
        let n = chunk.len() / per_image;
        let out = model.infer(chunk, n, size, size)?;
        for row in out.features.chunks(FEATURE_DIM) {
            if row.iter().any(|v| !v.is_finite()) {
                return Err(AeError::Python(format!(
                    "the feature of view {} is not finite",
                    rows.len()
                )));
            }
            rows.push(row.to_vec());
        }
    }
    if rows.len() != clouds.len() {
        return Err(AeError::Python(format!(
            "{} views gave {} features",
            clouds.len(),
            rows.len()
        )));
    }
    Ok(rows)
}

/// What [`dataset_features`] noticed besides the table.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FeatureStats {
    /// Views in which no object stood out of the table (cropped at the frame's centre).
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
    let dataset_err = |e: lgdm_pointcloud::dataset::DatasetError| AeError::Dataset(e.to_string());
    let manifest = ds.manifest();
    let total = manifest.views;
    let camera = manifest.camera;
    let background = table_frame(&camera);
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
                let view = view_image(cloud, &camera, &background)?;
                stats.empty_views += u64::from(view.empty);
                batch.extend(model.preprocess(&view.rgb, &view.depth_m, view.size, view.size)?);
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
    use lgdm_pointcloud::dataset::CameraSpec;
    use lgdm_pointcloud::objects::procedural_object;

    /// A mug's view (its mesh vertices in the turntable camera's frame) becomes a crop with the
    /// mug at its centre over the table; a cloud behind the camera leaves only the table.
    #[test]
    fn views_are_object_centred_crops_over_the_table() {
        let camera = CameraSpec::default().camera();
        let background = table_frame(&camera);
        let mug = procedural_object("mug", 0, 1).unwrap();
        // The mug's view as the dataset makes it (rendered, back-projected), without colours.
        let frame = render(
            &camera,
            &[RenderItem {
                mesh: &mug,
                world_from_object: Pose::identity(),
                label: 2,
            }],
        );
        let pts = frame.backproject(&camera, 2).points;
        let v = view_image(&PointCloud::new(pts, None), &camera, &background).unwrap();
        assert!(!v.empty);
        assert_eq!((v.rgb.len(), v.depth_m.len()), (3 * 224 * 224, 224 * 224));
        let centre = 112 * 224 + 112;
        assert_eq!(&v.rgb[3 * centre..3 * centre + 3], &[128, 128, 128]);
        // The corner is table (valid depth, farther than the mug).
        assert!(v.depth_m[0] > v.depth_m[centre]);
        let behind = PointCloud::new(vec![[0.0, 0.0, -1.0]], None);
        let v = view_image(&behind, &camera, &background).unwrap();
        assert!(v.empty);
        assert!(v.depth_m.iter().all(|&d| d > 0.0));
    }
}
