//! Objects, RGB-D rendering, sequential point clouds, augmentations, the GOOD descriptor and
//! MCAP datasets for lifelong 3D object recognition.
//!
//! The pipeline of `lgdm gen-dataset`: [`objects`] (procedural household objects) or
//! [`import`] (user meshes) → [`render`] (z-buffer RGB-D on a turntable) → [`augment`] →
//! [`dataset`] (MCAP collections in the `foxglove.PointCloud` schema + `manifest.json`) →
//! [`features`] (GOOD, written as `.npz`). Grasp-labelled RGB-D images in the Cornell layout
//! come from [`grasp`] and [`cornell`]; [`projection`] makes 224×224 images of clouds.
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
pub mod cloud;
pub mod cornell;
pub mod dataset;
pub mod features;
pub mod good;
pub mod grasp;
pub mod grasp_decode;
pub mod image;
pub mod import;
pub mod math;
pub mod mesh;
pub mod npz;
pub mod objects;
pub mod preview;
pub mod progress;
pub mod projection;
pub mod render;

pub use cloud::PointCloud;
pub use progress::Progress;
