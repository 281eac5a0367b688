//! Antipodal parallel-jaw grasp rectangles computed from the object's geometry.
//! (Synthesis functions follow; this part holds the parameters.)

use serde::{Deserialize, Serialize};

/// Gripper and sampling parameters of the grasp labels. Lengths in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GraspSpec {
    /// Largest opening of the parallel-jaw gripper (default: 0.085, a Robotiq 2F-85).
    pub max_opening_m: f32,
    /// Width of a finger pad across the opening axis (default: 0.02).
    pub finger_width_m: f32,
    /// How far the fingers reach below the top of the object at the grasp centre (default: 0.02).
    pub finger_depth_m: f32,
    /// Free space needed beyond each contact for the finger to close (default: 0.006).
    pub clearance_m: f32,
    /// Coulomb friction coefficient of the friction cone (default: 0.5, half-angle ≈ 26.6°).
    pub friction: f32,
    /// Candidate grasps sampled per image (default: 400).
    pub candidates_per_image: usize,
    /// Most positive rectangles kept per image (default: 30).
    pub max_positives: usize,
    /// Most negative (rejected) rectangles kept per image (default: 30).
    pub max_negatives: usize,
    /// Height of the top-down grasp camera above the table, metres (default: 0.6).
    pub camera_height_m: f32,
}

impl Default for GraspSpec {
    fn default() -> Self {
        Self {
            max_opening_m: 0.085,
            finger_width_m: 0.02,
            finger_depth_m: 0.02,
            clearance_m: 0.006,
            friction: 0.5,
            candidates_per_image: 400,
            max_positives: 30,
            max_negatives: 30,
            camera_height_m: 0.6,
        }
    }
}

impl GraspSpec {
    /// Checks the parameters, describing the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        if !pos(self.max_opening_m) || self.max_opening_m > 0.5 {
            return Err("max_opening_m must be in (0, 0.5]".into());
        }
        if !pos(self.finger_width_m) || !pos(self.finger_depth_m) || !pos(self.clearance_m) {
            return Err("finger_width_m, finger_depth_m and clearance_m must be positive".into());
        }
        if !pos(self.friction) {
            return Err("friction must be positive".into());
        }
        if !(self.camera_height_m.is_finite()
            && self.camera_height_m > 0.2
            && self.camera_height_m < 3.0)
        {
            return Err("camera_height_m must be in (0.2, 3)".into());
        }
        if self.candidates_per_image == 0 {
            return Err("candidates_per_image must be at least 1".into());
        }
        Ok(())
    }
}
