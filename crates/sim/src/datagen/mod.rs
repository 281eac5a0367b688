//! Data made with the robot's world: grasp training data and the paper's object set.

pub mod grasp_data;
pub mod object_sets;
