//! The autoencoder encoder (`--encoder ae`): every view's point cloud re-projected to a square
//! RGB-D image at the network's input size (`lgdm_pointcloud::projection`, as the paper and
//! DESIGN.md §4–5 describe), normalised by `train_ae.bridge.preprocess` and run through the
//! torch autoencoder in batches (`lgdm_pybridge::ae`) for its 256-d L2-normalised feature.
//!
//! Rows come in the GOOD table's order (collection, sequence in file order, frame), so
//! scenarios, the cache and `lgdm train` treat both encoders alike. Needs the cargo feature
//! `ae`; without it every entry point fails with how to rebuild and what to install.

use std::path::{Path, PathBuf};

use anyhow::Result;
use lgdm_pointcloud::dataset::Dataset;
use lgdm_pointcloud::features::FeatureTable;

use crate::progress::Reporter;

/// Version of the view → network-input pipeline (projection parameters, empty-view and
/// colourless-view handling). Part of the feature cache key: change it when the pipeline changes.
pub const PIPELINE: &str = "ae-projection-v1 margin=0.08 splat=auto empty=blank grey=128";

/// Why `--encoder ae` cannot run in a build without the `ae` feature, and what to do.
#[cfg_attr(feature = "ae", allow(dead_code))]
pub const NOT_BUILT: &str = "--encoder ae needs the torch autoencoder, and this `lgdm` binary was \
built without the `ae` feature (the default build neither links libpython nor needs torch). \
Rebuild it with `cargo build --release -p lgdm-cli --features ae`, and install torch and the \
autoencoder package into a venv: `python3 -m venv ~/.cache/lgdm/venv && \
~/.cache/lgdm/venv/bin/pip install -e python/train_ae` (or activate your own venv, or set \
LGDM_VENV to it); see the README, \"Grasp network\". Or use --encoder good";

/// The checkpoint to use: `explicit` (`--ae-checkpoint`), else the one shipped with train_ae.
#[cfg(not(feature = "ae"))]
pub fn resolve_checkpoint(_explicit: Option<&Path>) -> Result<PathBuf> {
    anyhow::bail!(NOT_BUILT)
}

/// Autoencoder features of every view.
#[cfg(not(feature = "ae"))]
pub fn features(_ds: &Dataset, _checkpoint: &Path, _reporter: &Reporter) -> Result<FeatureTable> {
    anyhow::bail!(NOT_BUILT)
}

#[cfg(feature = "ae")]
pub use with_ae::{features, resolve_checkpoint};

#[cfg(feature = "ae")]
mod with_ae {
    use super::*;

    use anyhow::{Context, bail};
    use lgdm_pointcloud::PointCloud;
    use lgdm_pointcloud::projection::{ProjectionError, ProjectionParams, project_to_image};
    use lgdm_pybridge::ae::{self, AeError, AutoEncoder, FEATURE_DIM};

    /// Images per inference call.
    pub const AE_BATCH: usize = 32;

    /// Colour of object pixels when a view has no colours.
    const GREY: u8 = 128;

    /// Maps bridge errors to messages that read well after `error: `.
    fn bridge_error(e: AeError) -> anyhow::Error {
        match e {
            AeError::NoDefaultCheckpoint(_) => anyhow::anyhow!(
                "--encoder ae: {e}; pass a checkpoint with --ae-checkpoint PATH (one written by \
                 `python -m train_ae.train`)"
            ),
            other => anyhow::Error::new(other).context("--encoder ae"),
        }
    }

    /// The checkpoint to use: `explicit` (`--ae-checkpoint`), else the one shipped with
    /// train_ae (`train_ae.bridge.default_checkpoint()`); absolute.
    pub fn resolve_checkpoint(explicit: Option<&Path>) -> Result<PathBuf> {
        let path = match explicit {
            Some(p) => {
                if !p.is_file() {
                    bail!("--ae-checkpoint {}: no such file", p.display());
                }
                p.to_path_buf()
            }
            None => ae::default_checkpoint().map_err(bridge_error)?,
        };
        std::fs::canonicalize(&path).with_context(|| format!("resolving {}", path.display()))
    }

    /// The network input of one view: (RGB bytes, depth in metres), `size`² pixels each; a
    /// blank image (all zeros) when no point lies in front of the camera. Object pixels of a
    /// colourless cloud are grey.
    pub(crate) fn view_image(
        cloud: &PointCloud,
        params: &ProjectionParams,
    ) -> Result<(Vec<u8>, Vec<f32>, bool)> {
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
                Ok((rgb, img.depth_m, false))
            }
            Err(ProjectionError::Empty) => Ok((vec![0; 3 * pixels], vec![0.0; pixels], true)),
            Err(e) => Err(e).context("projecting a view"),
        }
    }

    /// Autoencoder features of every view of `ds` (one row per view, in the GOOD table's
    /// order), [`AE_BATCH`] images per inference call.
    pub fn features(ds: &Dataset, checkpoint: &Path, reporter: &Reporter) -> Result<FeatureTable> {
        let model = AutoEncoder::load(checkpoint).map_err(bridge_error)?;
        let size = model.input_size();
        reporter.message(&format!(
            "autoencoder features: {} ({size}×{size} RGB-D input, batches of {AE_BATCH})",
            checkpoint.display()
        ));
        let params = ProjectionParams {
            size,
            ..ProjectionParams::default()
        };
        let manifest = ds.manifest();
        let total = manifest.views;
        let mut table = FeatureTable::new(FEATURE_DIM);
        let mut batch: Vec<f32> = Vec::with_capacity(AE_BATCH * 4 * size * size);
        let mut pending = 0usize;
        let mut empty_views = 0u64;
        let task = reporter.bar("AE features", total);
        let flush = |batch: &mut Vec<f32>, pending: &mut usize, table: &mut FeatureTable| {
            if *pending == 0 {
                return Ok::<(), anyhow::Error>(());
            }
            let out = model
                .infer(batch, *pending, size, size)
                .map_err(bridge_error)?;
            let first = table.features.len() / FEATURE_DIM;
            if let Some(i) = out.features.iter().position(|v| !v.is_finite()) {
                let row = first + i / FEATURE_DIM;
                bail!(
                    "--encoder ae: the feature of view {row} (collection {}, instance {}, frame \
                     {}) is not finite",
                    table.collection[row],
                    table.instance[row],
                    table.frame[row]
                );
            }
            table.features.extend_from_slice(&out.features);
            batch.clear();
            *pending = 0;
            task.update(
                "infer",
                table.features.len() as u64 / FEATURE_DIM as u64,
                total,
            );
            Ok(())
        };
        for c in 0..manifest.collections.len() as u32 {
            for seq in ds.sequences(c)? {
                let seq = seq?;
                let sequence = manifest.sequence_id(seq.collection, seq.instance);
                for (f, cloud) in seq.frames.iter().enumerate() {
                    let (rgb, depth_m, empty) = view_image(cloud, &params)?;
                    empty_views += u64::from(empty);
                    batch.extend(
                        model
                            .preprocess(&rgb, &depth_m, size, size)
                            .map_err(bridge_error)?,
                    );
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
        task.finish();
        if empty_views > 0 {
            reporter.message(&format!(
                "{empty_views} view(s) had no point in front of the camera: blank images"
            ));
        }
        table
            .check()
            .map_err(|e| anyhow::anyhow!("autoencoder feature table: {e}"))?;
        if table.len() as u64 != total {
            bail!(
                "the dataset's manifest records {total} views, its collections hold {}",
                table.len()
            );
        }
        Ok(table)
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
            let (rgb, depth, empty) =
                view_image(&PointCloud::new(pts.clone(), None), &params).unwrap();
            assert!(!empty);
            assert_eq!((rgb.len(), depth.len()), (3 * 256, 256));
            assert!(depth.iter().any(|&d| d > 0.0));
            for (px, &d) in rgb.chunks(3).zip(&depth) {
                assert_eq!(px[0], if d > 0.0 { GREY } else { 0 });
            }
            let colours = vec![[10u8, 20, 30]; pts.len()];
            let (rgb, _, _) = view_image(&PointCloud::new(pts, Some(colours)), &params).unwrap();
            assert!(rgb.chunks(3).any(|px| px == [10, 20, 30]));
            let behind = PointCloud::new(vec![[0.0, 0.0, -1.0]], None);
            let (rgb, depth, empty) = view_image(&behind, &params).unwrap();
            assert!(empty);
            assert!(rgb.iter().all(|&v| v == 0) && depth.iter().all(|&d| d == 0.0));
        }
    }
}
