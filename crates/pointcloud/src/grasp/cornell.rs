//! Grasp-labelled RGB-D images in the Cornell grasping dataset's layout, so existing Cornell
//! loaders read them:
//!
//! ```text
//! <root>/<nn>/pcdNNNNr.png      RGB, 8 bit
//! <root>/<nn>/pcdNNNNd.tiff     depth, float32 metres (0 = no data)
//! <root>/<nn>/pcdNNNNcpos.txt   positive rectangles: four "x y" corner lines each,
//! <root>/<nn>/pcdNNNNcneg.txt   negative rectangles  first edge along the opening axis
//! <root>/index.json             crop, finger width; per image: object, category, camera, window
//! ```
//!
//! Image `k` (from 0) is number `NNNN = 100 + k` in folder `nn = NNNN / 100`, as in the
//! original (`01/pcd0100r.png` …). Image `k` shows the seeded scene [`grasp_scene`]`(…, k, …)`.
//!
//! By default each image is the grasp network's input, the object-centred crop of
//! [`crate::crop`] (found by segmentation, not from labels), with the rectangles in crop pixels
//! and every rectangle's jaw the gripper's real finger width (`docs/DESIGN.md` §5); with
//! [`CornellExport::crop`] `None` the whole camera frame is written instead (for other tools).
//!
//! This module knows nothing of datasets: [`export_cornell`] takes the objects, their category
//! ids and a [`CornellExport`]; `dataset::generate` calls it for `<dataset>/grasp`.
//!
//! ```no_run
//! use lgdm_pointcloud::grasp::cornell::read_rectangles;
//! let rects = read_rectangles("grasp/01/pcd0100cpos.txt".as_ref()).unwrap();
//! println!("{} positive rectangles", rects.len());
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::decode::InputCrop;
use super::label::{GraspCandidate, GraspRectangle, GraspSpec, GraspVerdict, synthesize_grasps};
use crate::crop::{CropError, CropSpec, ObjectCrop, crop_largest_object};
use crate::image::{ImageError, RgbImage, write_depth_tiff};
use crate::math::{Pose, derive_seed, look_at, rotation_z, translation};
use crate::mesh::Mesh;
use crate::objects::ObjectModel;
use crate::progress::{Progress, par_map_with_progress};
use crate::render::{Camera, Intrinsics, RenderItem, RgbdFrame, render};
use crate::segment::SegmentParams;
use lgdm_base::fs::{write_atomic, write_json as write_json_atomic};

/// Errors of the Cornell export and reader. Each names the file.
#[derive(Debug, thiserror::Error)]
pub enum CornellError {
    /// File-system error on a path.
    #[error("cannot access {}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Writing an image failed.
    #[error("image {}: {reason}", path.display())]
    Image {
        /// The image path.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The object-centred crop of an image failed.
    #[error("grasp image {image}: {source}")]
    Crop {
        /// Image index (from 0).
        image: usize,
        /// What went wrong.
        #[source]
        source: CropError,
    },
    /// A rectangle file is not Cornell rectangle text.
    #[error("rectangle file {}: {reason}", path.display())]
    Rectangles {
        /// The text file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

impl CornellError {
    fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CornellError::Io {
            path: path.into(),
            source,
        }
    }
}

impl From<ImageError> for CornellError {
    fn from(e: ImageError) -> Self {
        CornellError::Image {
            path: e.path,
            reason: e.reason,
        }
    }
}

/// The largest number of images: Cornell numbers run from `pcd0100` to `pcd9998`.
pub const MAX_IMAGES: usize = 9_899;

/// Name of the index file in the Cornell root.
pub const INDEX_FILE: &str = "index.json";

/// Label of the table in grasp scenes.
pub const TABLE_LABEL: u8 = 1;
/// Label of the object in grasp scenes.
pub const OBJECT_LABEL: u8 = 2;

const TAG_GRASP_SCENE: u64 = 0x6A5;

/// One rendered grasp scene with its evaluated candidates.
#[derive(Debug, Clone)]
pub struct GraspScene {
    /// The top-down camera.
    pub camera: Camera,
    /// RGB-D frame (table and object).
    pub frame: RgbdFrame,
    /// Where the object stands.
    pub world_from_object: Pose,
    /// Accepted and rejected candidates.
    pub candidates: Vec<GraspCandidate>,
}

impl GraspScene {
    /// Positive rectangles.
    pub fn positives(&self) -> Vec<GraspRectangle> {
        self.candidates
            .iter()
            .filter(|c| c.verdict == GraspVerdict::Accepted)
            .map(|c| c.rectangle)
            .collect()
    }

    /// Negative rectangles.
    pub fn negatives(&self) -> Vec<GraspRectangle> {
        self.candidates
            .iter()
            .filter(|c| c.verdict != GraspVerdict::Accepted)
            .map(|c| c.rectangle)
            .collect()
    }
}

/// A wooden table top, 1.4 m square, at z = 0.
pub fn table_mesh() -> Mesh {
    let mut m = Mesh::new();
    let (h, c) = (0.7, [150, 118, 84]);
    m.push_triangle([-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], c);
    m.push_triangle([-h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0], c);
    m
}

/// Renders object `object` for grasp image `image` (seeded placement and camera) and
/// synthesises its grasp rectangles.
pub fn grasp_scene(spec: &GraspSpec, seed: u64, image: usize, object: &ObjectModel) -> GraspScene {
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(seed, TAG_GRASP_SCENE, image as u64, 0));
    let yaw = rng.random_range(0.0..std::f32::consts::TAU);
    let (dx, dy) = (rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
    let world_from_object = translation([dx, dy, 0.0]) * rotation_z(yaw);
    // Nearly top-down camera, slightly off-centre, image "up" along world +y.
    let eye = [
        rng.random_range(-0.04..0.04),
        rng.random_range(-0.04..0.04),
        spec.camera_height_m,
    ];
    let camera = Camera::new(
        Intrinsics::kinect_vga(),
        look_at(eye, [dx * 0.5, dy * 0.5, 0.0], [0.0, 1.0, 0.0]),
    );
    let table = table_mesh();
    let frame = render(
        &camera,
        &[
            RenderItem {
                mesh: &table,
                world_from_object: Pose::identity(),
                label: TABLE_LABEL,
            },
            RenderItem {
                mesh: &object.mesh,
                world_from_object,
                label: OBJECT_LABEL,
            },
        ],
    );
    let mesh_world = object.mesh.transformed(&world_from_object);
    let candidates = synthesize_grasps(&mesh_world, &frame, &camera, OBJECT_LABEL, spec, &mut rng);
    GraspScene {
        camera,
        frame,
        world_from_object,
        candidates,
    }
}

/// Cornell number of image `k`: `100 + k`.
pub fn cornell_number(k: usize) -> usize {
    100 + k
}

/// Path prefix `<root>/<nn>/pcdNNNN` of Cornell number `number`.
pub fn cornell_prefix(root: &Path, number: usize) -> PathBuf {
    root.join(format!("{:02}", number / 100))
        .join(format!("pcd{number:04}"))
}

/// Writes rectangles as Cornell text: four `x y` lines per rectangle (shortest round-trip
/// float formatting, so reading gives the same values back).
pub fn write_rectangles(path: &Path, rectangles: &[GraspRectangle]) -> Result<(), CornellError> {
    let mut text = String::new();
    for r in rectangles {
        for [x, y] in r.corners_px {
            let _ = writeln!(text, "{x} {y}");
        }
    }
    write_atomic(path, |w| std::io::Write::write_all(w, text.as_bytes()))
        .map_err(|e| CornellError::io(path, e))
}

/// Reads Cornell rectangle text (`cpos.txt` / `cneg.txt`). Blank lines are ignored; a line
/// that is not two numbers, a NaN, or a count of corners not divisible by four is an error.
pub fn read_rectangles(path: &Path) -> Result<Vec<GraspRectangle>, CornellError> {
    let text = std::fs::read_to_string(path).map_err(|e| CornellError::io(path, e))?;
    let bad = |reason: String| CornellError::Rectangles {
        path: path.to_path_buf(),
        reason,
    };
    let mut corners = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let mut it = line.split_whitespace().map(str::parse::<f32>);
        match (it.next(), it.next(), it.next()) {
            (Some(Ok(x)), Some(Ok(y)), None) if x.is_finite() && y.is_finite() => {
                corners.push([x, y])
            }
            _ => {
                return Err(bad(format!(
                    "line {}: expected two numbers `x y`, got `{line}`",
                    n + 1
                )));
            }
        }
    }
    if corners.len() % 4 != 0 {
        return Err(bad(format!(
            "{} corner lines is not a multiple of 4",
            corners.len()
        )));
    }
    Ok(corners
        .chunks_exact(4)
        .map(|c| GraspRectangle {
            corners_px: [c[0], c[1], c[2], c[3]],
        })
        .collect())
}

/// Format tag of `index.json`.
pub const INDEX_FORMAT: &str = "lgdm.grasp.v2";

/// `index.json`: how the images were made and one entry per image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspIndex {
    /// [`INDEX_FORMAT`].
    pub format: String,
    /// The object-centred crop of every image; `None`: whole camera frames.
    pub crop: Option<CropSpec>,
    /// Finger width of the gripper, metres: the jaw of every rectangle.
    pub finger_width_m: f32,
    /// With a crop: jaw length in pixels as a fraction of the image (or label map) side,
    /// `finger_width_m / crop.side_m` — what decoders use for the jaw.
    pub jaw_side_fraction: Option<f32>,
    /// The images in order.
    pub images: Vec<GraspImageInfo>,
}

/// One entry of `index.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspImageInfo {
    /// Cornell number (`100 + k`).
    pub number: usize,
    /// Path prefix relative to the grasp root (`01/pcd0100`).
    pub prefix: String,
    /// Instance id (index in the manifest's instances).
    pub instance: u32,
    /// Category id.
    pub category: u32,
    /// Category name.
    pub category_name: String,
    /// Instance name.
    pub object: String,
    /// The camera (depth is its optical z).
    pub camera: Camera,
    /// Where the crop sits in the camera frame (crop pixel → frame pixel); `None` for whole
    /// frames.
    pub window: Option<InputCrop>,
    /// Number of positive rectangles.
    pub positives: usize,
    /// Number of negative rectangles.
    pub negatives: usize,
    /// Labels from physics (`lgdm sim grasp-data`): the scene the image is of and the outcome
    /// of each rectangle, tried in simulation. `None` for the geometric labels of
    /// `gen-dataset` (the key is then absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub physics: Option<PhysicsLabels>,
}

/// How an image's rectangles were labelled by physics: the scene and one [`GraspOutcome`] per
/// rectangle, in the order of `cpos.txt` (successes) and `cneg.txt` (failures).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhysicsLabels {
    /// The scene's number in the set.
    pub scene: usize,
    /// Its table (`isolated`, `packed`, `pile`, `scattered`).
    pub scenario: String,
    /// The objects on the table (instance names), the imaged one among them.
    pub objects: Vec<String>,
    /// The outcomes of the positive rectangles.
    pub positives: Vec<GraspOutcome>,
    /// The outcomes of the negative rectangles.
    pub negatives: Vec<GraspOutcome>,
}

/// What happened when one rectangle was tried.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspOutcome {
    /// The grasp source that proposed it (`analytic`, `random`, `rim`).
    pub source: String,
    /// Its rank among that source's proposals (0 = best).
    pub rank: usize,
    /// The grasp held.
    pub success: bool,
    /// Why not (`missed`, `slipped_during_lift`, `collision_on_approach`).
    pub reason: Option<String>,
    /// The robot's planner would try it: both pads reach a surface as they close.
    pub reaches_contacts: bool,
}

/// What [`export_cornell`] writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornellExport<'a> {
    /// Number of images, at most [`MAX_IMAGES`]; image `k` shows object `k mod objects`.
    pub images: usize,
    /// Seed of the scenes (placement, camera, candidate sampling).
    pub seed: u64,
    /// Gripper and sampling parameters of the labels.
    pub grasp: &'a GraspSpec,
    /// The object-centred crop written (default in datasets: [`CropSpec::default`]); `None`
    /// writes whole camera frames.
    pub crop: Option<CropSpec>,
}

/// Writes `export.images` grasp-labelled images of `objects` (cycling through them) into
/// `root` in the Cornell layout, then `root/index.json`, and returns the index. `categories[i]`
/// is the category id recorded for `objects[i]`, whose instance id is `i`; `category_names`
/// is indexed by category id. Images are made in
/// parallel; the files do not depend on the number of threads. `progress` is called on the
/// calling thread (stage `grasp images`).
///
/// # Panics
///
/// If `categories` and `objects` differ in length.
pub fn export_cornell(
    root: &Path,
    export: &CornellExport<'_>,
    objects: &[ObjectModel],
    categories: &[u32],
    category_names: &[String],
    progress: &mut dyn FnMut(Progress),
) -> Result<GraspIndex, CornellError> {
    assert_eq!(
        objects.len(),
        categories.len(),
        "one category id per object"
    );
    if let Some(crop) = &export.crop {
        crop.validate()
            .map_err(|source| CornellError::Crop { image: 0, source })?;
    }
    let finger_width_m = export.grasp.finger_width_m;
    let mut index = GraspIndex {
        format: INDEX_FORMAT.to_string(),
        crop: export.crop,
        finger_width_m,
        jaw_side_fraction: export.crop.map(|c| c.side_fraction(finger_width_m)),
        images: Vec::new(),
    };
    let total = export.images;
    if total == 0 || objects.is_empty() {
        return Ok(index);
    }
    // After a failure the remaining images are skipped (`None`).
    let failed = AtomicBool::new(false);
    let mut done = 0u64;
    let results = par_map_with_progress(
        total,
        |k, tick| {
            if failed.load(Ordering::SeqCst) {
                return None;
            }
            let o = k % objects.len();
            let category = categories[o];
            let name = category_names
                .get(category as usize)
                .cloned()
                .unwrap_or_else(|| category.to_string());
            let r = write_grasp_image(export, root, k, &objects[o], o as u32, category, name);
            if r.is_err() {
                failed.store(true, Ordering::SeqCst);
            }
            tick(1);
            Some(r)
        },
        &mut |n| {
            done += n;
            progress(Progress {
                stage: "grasp images",
                done,
                total: total as u64,
            });
        },
    );
    index.images = results
        .into_iter()
        .flatten()
        .collect::<Result<Vec<GraspImageInfo>, CornellError>>()?;
    debug_assert_eq!(
        index.images.len(),
        total,
        "no image is skipped without a failure"
    );
    let index_path = root.join(INDEX_FILE);
    write_json_atomic(&index_path, &index).map_err(|e| CornellError::io(&index_path, e))?;
    Ok(index)
}

fn write_grasp_image(
    export: &CornellExport<'_>,
    root: &Path,
    k: usize,
    object: &ObjectModel,
    instance: u32,
    category: u32,
    category_name: String,
) -> Result<GraspImageInfo, CornellError> {
    let scene = grasp_scene(export.grasp, export.seed, k, object);
    let number = cornell_number(k);
    let prefix = cornell_prefix(root, number);
    let dir = prefix.parent().expect("prefix has a folder");
    std::fs::create_dir_all(dir).map_err(|e| CornellError::io(dir, e))?;
    let with = |suffix: &str| PathBuf::from(format!("{}{suffix}", prefix.display()));
    let f = &scene.frame;
    let (mut pos, mut neg) = (scene.positives(), scene.negatives());
    let window = match &export.crop {
        None => {
            let (w, h) = (f.width as usize, f.height as usize);
            RgbImage::from_pixels(w, h, f.rgb.clone()).write_png(&with("r.png"))?;
            write_depth_tiff(&with("d.tiff"), w, h, &f.depth_m)?;
            None
        }
        Some(spec) => {
            let found = crop_largest_object(
                f,
                &scene.camera.intrinsics,
                &SegmentParams::whole_components(),
                spec,
            )
            .map_err(|source| CornellError::Crop { image: k, source })?;
            let crop = found.crop;
            let n = crop.size_px as usize;
            let jaw_px = spec.size_px as f32 * spec.side_fraction(export.grasp.finger_width_m);
            pos = rectangles_in_crop(&pos, &crop, jaw_px);
            neg = rectangles_in_crop(&neg, &crop, jaw_px);
            RgbImage::from_pixels(n, n, crop.rgb.clone()).write_png(&with("r.png"))?;
            write_depth_tiff(&with("d.tiff"), n, n, &crop.depth_m)?;
            Some(crop.window)
        }
    };
    write_rectangles(&with("cpos.txt"), &pos)?;
    write_rectangles(&with("cneg.txt"), &neg)?;
    Ok(GraspImageInfo {
        number,
        prefix: format!("{:02}/pcd{number:04}", number / 100),
        instance,
        category,
        category_name,
        object: object.name.clone(),
        camera: scene.camera,
        window,
        positives: pos.len(),
        negatives: neg.len(),
        physics: None,
    })
}

/// Rectangles of the camera frame in crop pixels, the jaw set to `jaw_px` (the finger width at
/// the crop's scale); those whose centre falls outside the crop are dropped.
pub fn rectangles_in_crop(
    rectangles: &[GraspRectangle],
    crop: &ObjectCrop,
    jaw_px: f32,
) -> Vec<GraspRectangle> {
    let size = crop.size_px as f32;
    rectangles
        .iter()
        .filter_map(|r| {
            let c = r.corners_px.map(|p| crop.crop_from_frame(p));
            let centre = crop.crop_from_frame(r.center());
            let inside = |v: f32| (-0.5..size - 0.5).contains(&v);
            if !(inside(centre[0]) && inside(centre[1])) {
                return None;
            }
            let along = [c[1][0] - c[0][0], c[1][1] - c[0][1]];
            let across = [c[2][0] - c[1][0], c[2][1] - c[1][1]];
            let (la, lc) = (along[0].hypot(along[1]), across[0].hypot(across[1]));
            if la <= 0.0 || lc <= 0.0 {
                return None;
            }
            let u = [along[0] / 2.0, along[1] / 2.0];
            let v = [across[0] / lc * jaw_px / 2.0, across[1] / lc * jaw_px / 2.0];
            let [x, y] = centre;
            Some(GraspRectangle {
                corners_px: [
                    [x - u[0] - v[0], y - u[1] - v[1]],
                    [x + u[0] - v[0], y + u[1] - v[1]],
                    [x + u[0] + v[0], y + u[1] + v[1]],
                    [x - u[0] + v[0], y - u[1] + v[1]],
                ],
            })
        })
        .collect()
}

/// Draws rectangles on an image: positives green with the jaw edges highlighted, negatives
/// thin red.
pub fn draw_rectangles(
    img: &mut RgbImage,
    positives: &[GraspRectangle],
    negatives: &[GraspRectangle],
) {
    for r in negatives {
        let c = r.corners_px;
        for i in 0..4 {
            img.draw_line(c[i], c[(i + 1) % 4], [220, 40, 40], 1);
        }
    }
    for r in positives {
        let c = r.corners_px;
        // Opening-axis edges (0→1, 2→3) thin green; jaw edges (1→2, 3→0) thick blue.
        img.draw_line(c[0], c[1], [40, 220, 60], 1);
        img.draw_line(c[2], c[3], [40, 220, 60], 1);
        img.draw_line(c[1], c[2], [40, 120, 255], 2);
        img.draw_line(c[3], c[0], [40, 120, 255], 2);
    }
}
