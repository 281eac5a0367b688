//! Grasps for a parallel-jaw gripper, from labels to decoded poses:
//!
//! - [`label`]: grasp rectangles computed from an object's geometry (antipodal contacts inside
//!   the friction cone, gripper width, free finger lanes): [`GraspSpec`], [`GraspRectangle`],
//!   [`synthesize_grasps`].
//! - [`cornell`]: seeded top-down grasp scenes ([`grasp_scene`]) written as grasp-labelled
//!   RGB-D images in the Cornell grasping dataset's layout ([`export_cornell`]), and the
//!   rectangle text files read back ([`read_rectangles`]).
//! - [`analytic`]: antipodal grasps computed from an object-centred crop's depth image alone
//!   ([`analytic_grasps`]), in the decoded grasps' conventions — the robot's grasp source
//!   without a network.
//! - [`decode`]: the grasp network's pixel-wise maps → ranked rectangles → 3-D grasp poses in
//!   the camera frame ([`decode_grasps`], [`grasp_pose`]), and rectangles → training maps
//!   ([`grasp_maps`]), with train_ae's conventions.
//!
//! Nothing here depends on the `dataset` module; the dataset generator calls
//! [`export_cornell`].
//!
//! ```
//! use lgdm_pointcloud::grasp::{GraspRectangle, GraspSpec, grasp_scene};
//! use lgdm_pointcloud::objects::{ObjectModel, procedural_object};
//! let object = ObjectModel {
//!     name: "mug_01".into(),
//!     category: "mug".into(),
//!     mesh: procedural_object("mug", 0, 0).unwrap(),
//!     physics: Default::default(),
//!     parts: Vec::new(),
//! };
//! let scene = grasp_scene(&GraspSpec::default(), 0, 0, &object);
//! let positives: Vec<GraspRectangle> = scene.positives();
//! assert!(!positives.is_empty());
//! ```

pub mod analytic;
pub mod cornell;
pub mod decode;
pub mod label;

pub use analytic::{
    AnalyticError, AnalyticGrasp, AnalyticParams, analytic_grasps, analytic_grasps_detailed,
};
pub use cornell::{
    CornellError, CornellExport, GraspImageInfo, GraspScene, export_cornell, grasp_scene,
    read_rectangles, write_rectangles,
};
pub use decode::{
    DecodedGrasp, GraspDecodeError, GraspDecodeParams, GraspMaps, GraspMapsView, GraspPose,
    InputCrop, decode_grasps, grasp_maps, grasp_pose,
};
pub use label::{
    GraspCandidate, GraspRectangle, GraspSpec, GraspVerdict, evaluate_grasp, evaluate_grasp_at,
    synthesize_grasps,
};
