//! Data made in the robot's world: grasp training data tried by the free gripper
//! ([`grasp_data`]), the paper's object set laid out for `--meshes` ([`object_sets`]), irregular
//! shapes generated for the same ([`irregular`]) and the `ycb` dataset preset: the YCB meshes
//! grouped into categories ([`ycb_dataset`]).

pub mod grasp_data;
pub mod irregular;
pub mod object_sets;
pub mod ycb_dataset;
