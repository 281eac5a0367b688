//! Sequential point-cloud datasets: generation ([`generate`]) and streaming, validating
//! reading ([`Dataset`]).
//!
//! On disk a dataset is a directory:
//!
//! ```text
//! manifest.json                      categories, instances, collections, split, seed, spec
//! collections/cNN_<name>.mcap        one MCAP file per collection, one channel per object
//!                                    sequence, messages in the foxglove.PointCloud schema
//! grasp/<nn>/pcdNNNN{r.png,d.tiff,cpos.txt,cneg.txt}, grasp/index.json   (Cornell layout)
//! contact_sheet.png, grasp_preview.png
//! ```
//!
//! Labels live in each channel's metadata (`collection`, `category`, `instance`, and their
//! names) and each message's MCAP sequence number is its frame index; log time is
//! `frame / fps`.
//!
//! ```no_run
//! use lgdm_pointcloud::dataset::{generate, Dataset, DatasetSpec};
//! let spec = DatasetSpec::small(7);
//! let manifest = generate(&spec, "data".as_ref(), &mut |_| {}).unwrap();
//! let ds = Dataset::open("data".as_ref()).unwrap();
//! for seq in ds.sequences(0).unwrap() {
//!     let seq = seq.unwrap();
//!     assert_eq!(seq.frames.len(), manifest.frames_per_sequence);
//! }
//! ```

mod generate;
pub(crate) mod mcap_io;
mod spec;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::augment::Augmentation;
pub use crate::cloud::PointCloud;
pub use crate::progress::Progress;
use crate::render::Camera;
pub use generate::{
    LoadedObjects, check_output_dir, generate, generate_from_meshes, label_ids, load_objects,
    render_views, view_cloud,
};
pub use mcap_io::{
    POINT_CLOUD_FRAME_ID, SequenceReader, decode_point_cloud, encode_point_cloud, foxglove_pose,
    foxglove_schema, foxglove_timestamp, foxglove_writer, point_cloud_schema,
};
pub use spec::{CameraSpec, CollectionSpec, DatasetSpec, Split, standard_collections};

/// Name of the manifest file in a dataset directory.
pub const MANIFEST_FILE: &str = "manifest.json";
/// Identifies the on-disk format in the manifest.
pub const FORMAT_NAME: &str = "lgdm-dataset";
/// Version of the on-disk format.
pub const FORMAT_VERSION: u32 = 1;
/// The most views per sequence a manifest may declare (the spec's own bound).
pub const MAX_FRAMES_PER_SEQUENCE: usize = 100_000;

/// Errors of dataset generation and reading. Each says what went wrong and where.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A spec field is out of range.
    #[error("invalid dataset spec: field `{field}`: {reason}")]
    InvalidSpec {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// File-system error on a path.
    #[error("cannot access {}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A user mesh could not be imported.
    #[error(transparent)]
    Mesh(#[from] crate::import::MeshImportError),
    /// The manifest is missing, unreadable or inconsistent.
    #[error("manifest {}: {reason}", path.display())]
    Manifest {
        /// The manifest path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A collection file is truncated, corrupt or does not match the manifest.
    #[error("collection file {}: {reason}", path.display())]
    Corrupt {
        /// The MCAP file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// No collection with this index.
    #[error("no collection {index} (the dataset has {count})")]
    NoSuchCollection {
        /// Requested index.
        index: u32,
        /// Number of collections.
        count: usize,
    },
    /// A rendered view had no object point.
    #[error(
        "collection {collection}, object `{object}`, frame {frame}: the object is not visible (check the camera spec)"
    )]
    EmptyView {
        /// Collection index.
        collection: u32,
        /// Object name.
        object: String,
        /// Frame index.
        frame: u32,
    },
    /// The GOOD descriptor failed on a view.
    #[error("collection {collection}, instance {instance}, frame {frame}: GOOD descriptor failed")]
    Good {
        /// Collection index.
        collection: u32,
        /// Instance id.
        instance: u32,
        /// Frame index.
        frame: u32,
        /// The descriptor error.
        #[source]
        source: crate::good::GoodError,
    },
    /// Writing an image failed.
    #[error("image {}: {reason}", path.display())]
    Image {
        /// The image path.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The object-centred crop of a grasp image failed.
    #[error("grasp image {image}: {source}")]
    GraspCrop {
        /// Image index (from 0).
        image: usize,
        /// What went wrong.
        #[source]
        source: crate::crop::CropError,
    },
    /// Generation was cancelled because another worker failed.
    #[error("cancelled")]
    Cancelled,
    /// A computed feature table does not describe its dataset (rows, labels, dimension or
    /// non-finite values; see `FeatureTable::check_dataset`).
    #[error("feature table of the dataset {}: {reason}", dataset.display())]
    FeatureTable {
        /// The dataset directory.
        dataset: PathBuf,
        /// What does not match.
        reason: String,
    },
}

impl DatasetError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        DatasetError::Io {
            path: path.into(),
            source,
        }
    }
}

impl From<crate::image::ImageError> for DatasetError {
    fn from(e: crate::image::ImageError) -> Self {
        DatasetError::Image {
            path: e.path,
            reason: e.reason,
        }
    }
}

/// The grasp export's errors become the dataset's variants with the same message.
impl From<crate::grasp::CornellError> for DatasetError {
    fn from(e: crate::grasp::CornellError) -> Self {
        use crate::grasp::CornellError as C;
        match e {
            C::Io { path, source } => DatasetError::Io { path, source },
            C::Image { path, reason } => DatasetError::Image { path, reason },
            C::Rectangles { path, reason } => DatasetError::Corrupt { path, reason },
            C::Crop { image, source } => DatasetError::GraspCrop { image, source },
        }
    }
}

/// One object of the dataset. Its index in [`Manifest::instances`] is its global instance id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InstanceInfo {
    /// Unique instance name (`mug_03`, or the mesh file's stem).
    pub name: String,
    /// Category id: index in [`Manifest::categories`].
    pub category: u32,
    /// `procedural` or the imported mesh file relative to the meshes directory.
    pub source: String,
    /// For an imported mesh: its file, unit (guessed or given) and largest extent in metres;
    /// absent for procedural objects.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub import: Option<crate::import::ImportReport>,
}

/// One collection file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollectionInfo {
    /// Collection index (0-based, file order).
    pub index: u32,
    /// Collection name.
    pub name: String,
    /// The augmentation, described with its parameters (`gaussian_noise(sigma=4mm)`).
    pub augmentation: String,
    /// The augmentation's exact parameters.
    pub augmentation_params: Augmentation,
    /// Train or test.
    pub split: Split,
    /// The MCAP file, relative to the dataset directory.
    pub file: String,
    /// Number of object sequences (one per instance).
    pub sequences: u32,
    /// Number of views.
    pub views: u64,
    /// File size in bytes (a cheap truncation check when opening).
    pub bytes: u64,
}

/// The grasp-labelled image set (Cornell layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspSetInfo {
    /// Root directory of the Cornell layout, relative to the dataset directory.
    pub dir: String,
    /// Number of images.
    pub images: usize,
    /// Index file (image number → object, camera), relative to the dataset directory.
    pub index: String,
}

/// `manifest.json`: what a dataset holds and how it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// On-disk format version ([`FORMAT_VERSION`]).
    pub format_version: u32,
    /// `lgdm-pointcloud <version>`.
    pub generator_version: String,
    /// The preset the spec came from.
    pub preset: String,
    /// The seed.
    pub seed: u64,
    /// Category names; a category id is an index here.
    pub categories: Vec<String>,
    /// Objects; an instance id is an index here.
    pub instances: Vec<InstanceInfo>,
    /// Collections in index order.
    pub collections: Vec<CollectionInfo>,
    /// Views per sequence.
    pub frames_per_sequence: usize,
    /// Frame rate, frames per second.
    pub fps: f32,
    /// Total number of views.
    pub views: u64,
    /// The turntable camera (points are in its optical frame).
    pub camera: Camera,
    /// `frame_id` of the point clouds.
    pub point_frame: String,
    /// The grasp-labelled images, if any.
    pub grasp: Option<GraspSetInfo>,
    /// Preview images written, relative paths.
    pub previews: Vec<String>,
    /// The full spec that generated the dataset.
    pub spec: DatasetSpec,
}

impl Manifest {
    /// Reads and checks `manifest.json` in `dir`.
    pub fn load(dir: &Path) -> Result<Manifest, DatasetError> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| DatasetError::io(&path, e))?;
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| DatasetError::Manifest {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        manifest
            .check()
            .map_err(|reason| DatasetError::Manifest { path, reason })?;
        Ok(manifest)
    }

    fn check(&self) -> Result<(), String> {
        if self.format != FORMAT_NAME {
            return Err(format!(
                "format is `{}`, expected `{FORMAT_NAME}`",
                self.format
            ));
        }
        if self.format_version != FORMAT_VERSION {
            return Err(format!(
                "format version {} is not supported (this build reads {FORMAT_VERSION})",
                self.format_version
            ));
        }
        for (i, inst) in self.instances.iter().enumerate() {
            if inst.category as usize >= self.categories.len() {
                return Err(format!(
                    "instance {i} `{}` has category {} out of range",
                    inst.name, inst.category
                ));
            }
        }
        for (i, c) in self.collections.iter().enumerate() {
            if c.index as usize != i {
                return Err(format!("collection {i} has index {}", c.index));
            }
            if c.file.contains("..") || Path::new(&c.file).is_absolute() {
                return Err(format!(
                    "collection {i} file `{}` leaves the dataset directory",
                    c.file
                ));
            }
        }
        if self.frames_per_sequence == 0 || self.frames_per_sequence > MAX_FRAMES_PER_SEQUENCE {
            return Err(format!(
                "frames_per_sequence is {}, expected 1..={MAX_FRAMES_PER_SEQUENCE}",
                self.frames_per_sequence
            ));
        }
        // Every collection holds one sequence per instance (the reader requires it), so the
        // counts follow from the lists; checked arithmetic, as the numbers are the file's.
        let per_collection = (self.instances.len() as u64)
            .checked_mul(self.frames_per_sequence as u64)
            .ok_or("instances × frames_per_sequence overflows")?;
        let mut total = 0u64;
        for (i, c) in self.collections.iter().enumerate() {
            if c.sequences as usize != self.instances.len() {
                return Err(format!(
                    "collection {i} has {} sequences, the manifest lists {} instances",
                    c.sequences,
                    self.instances.len()
                ));
            }
            if c.views != per_collection {
                return Err(format!(
                    "collection {i} has {} views, expected {} instances × {} frames = {per_collection}",
                    c.views,
                    self.instances.len(),
                    self.frames_per_sequence
                ));
            }
            total = total
                .checked_add(c.views)
                .ok_or("the views of the collections overflow")?;
        }
        if self.views != total {
            return Err(format!(
                "views is {}, the collections hold {total}",
                self.views
            ));
        }
        Ok(())
    }

    /// Indices of the collections in `split`.
    pub fn collections_in(&self, split: Split) -> Vec<u32> {
        self.collections
            .iter()
            .filter(|c| c.split == split)
            .map(|c| c.index)
            .collect()
    }

    /// Unique id of the sequence of `instance` in `collection`: `collection × instances + instance`.
    pub fn sequence_id(&self, collection: u32, instance: u32) -> u64 {
        u64::from(collection) * self.instances.len() as u64 + u64::from(instance)
    }
}

/// One object's sequence of views in one collection.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    /// Collection index.
    pub collection: u32,
    /// Category id.
    pub category: u32,
    /// Instance id.
    pub instance: u32,
    /// Views in frame order (points in metres, camera optical frame).
    pub frames: Vec<PointCloud>,
}

/// An opened dataset directory.
#[derive(Debug, Clone)]
pub struct Dataset {
    dir: PathBuf,
    manifest: Manifest,
}

impl Dataset {
    /// Opens a dataset: reads and checks the manifest and that every collection file exists
    /// with the recorded size.
    pub fn open(dir: &Path) -> Result<Dataset, DatasetError> {
        let manifest = Manifest::load(dir)?;
        for c in &manifest.collections {
            let path = dir.join(&c.file);
            let meta = std::fs::metadata(&path).map_err(|e| DatasetError::io(&path, e))?;
            if meta.len() != c.bytes {
                return Err(DatasetError::Corrupt {
                    path,
                    reason: format!(
                        "size is {} bytes, the manifest records {} (truncated or replaced)",
                        meta.len(),
                        c.bytes
                    ),
                });
            }
        }
        Ok(Dataset {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The dataset directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Streams the sequences of one collection in file order, validating as it goes: CRCs,
    /// schema, labels against the manifest, frame numbering and counts. After an error the
    /// iterator ends.
    pub fn sequences(&self, collection: u32) -> Result<SequenceReader, DatasetError> {
        let info = self.manifest.collections.get(collection as usize).ok_or(
            DatasetError::NoSuchCollection {
                index: collection,
                count: self.manifest.collections.len(),
            },
        )?;
        SequenceReader::open(&self.dir.join(&info.file), collection, &self.manifest)
    }
}
