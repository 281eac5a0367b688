//! Data made in the robot's world: grasp training data tried by the free gripper
//! ([`grasp_data`]) and the paper's object set laid out for `--meshes` ([`object_sets`]).

pub mod grasp_data;
pub mod object_sets;
