//! Objects, RGB-D rendering, sequential point clouds, augmentations, the GOOD descriptor and
//! MCAP datasets for lifelong 3D object recognition.
//!
//! The pipeline of `lgdm gen-dataset`: [`objects`] (procedural household objects) or
//! [`import`] (user meshes) → [`render`] (z-buffer RGB-D on a turntable) → [`augment`] →
//! [`dataset`] (MCAP collections in the `foxglove.PointCloud` schema + `manifest.json`) →
//! [`features`] (GOOD, written as `.npz`). [`grasp`] labels grasps from geometry, writes
//! grasp-labelled RGB-D images in the Cornell layout and decodes the grasp network's maps;
//! [`sensor`] gives rendered depth a real camera's noise and missing pixels; [`segment`] finds
//! the table and the objects on it in an RGB-D frame and [`crop`] cuts the
//! grasp network's object-centred, fixed-scale input around one;
//! [`projection`] makes 224×224 images of clouds; [`cache`] holds the embedded default
//! dataset and cached feature tables. Every file is written atomically (temp file,
//! then rename); parallel work runs on rayon's pool and never changes the bytes written.
//!
//! Lengths are metres, angles radians; clouds are in the camera's optical frame.
//!
//! ```
//! use lgdm_pointcloud::good::good_descriptor;
//! use lgdm_pointcloud::objects::procedural_object;
//! let mug = procedural_object("mug", 0, 1).unwrap();
//! let d = good_descriptor(&mug.vertices, 15).unwrap();
//! assert_eq!(d.len(), 675);
//! ```

#![warn(missing_docs)]

pub mod augment;
pub mod cache;
pub mod cloud;
pub mod crop;
pub mod dataset;
pub mod features;
pub mod good;
pub mod grasp;
pub mod image;
pub mod import;
pub mod math;
pub mod mesh;
pub mod npz;
pub mod objects;
pub mod parts;
pub mod preview;
pub mod progress;
pub mod projection;
pub mod render;
pub mod segment;
pub mod sensor;
pub mod sidecar;

pub use cloud::PointCloud;
pub use lgdm_base::fs::{DirLock, LOCK_FILE};
pub use progress::Progress;
