//! Every constant of a sim run in one serde struct, [`SimConfig`]: the world, the robot, the
//! cameras, the attempt's motions and judging, how tables are set, the objects' colliders. Each
//! part's defaults are its own; [`crate::spec`] checks the whole (`SimConfig::validate`).
//!
//! ```
//! use lgdm_sim::config::SimConfig;
//! let config = SimConfig::default();
//! assert_eq!(config.grasp_spec().max_opening_m, config.robot.gripper.stroke_m);
//! ```

use lgdm_pointcloud::grasp::GraspSpec;
use serde::{Deserialize, Serialize};

use crate::attempt::AttemptConfig;
use crate::camera::CameraConfig;
use crate::robot::RobotConfig;
use crate::scenario::ScenarioConfig;
use crate::shapes::ShapeConfig;
use crate::world::WorldConfig;

/// Every constant of a sim run. Defaults are each part's.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// The physics world.
    pub world: WorldConfig,
    /// The robot (arm and gripper).
    pub robot: RobotConfig,
    /// Cameras, crop and segmentation.
    pub cameras: CameraConfig,
    /// Motions and judging of one attempt.
    pub attempt: AttemptConfig,
    /// How tables are set and rounds end.
    pub scenario: ScenarioConfig,
    /// Objects' collider shapes (default: a convex decomposition of each mesh).
    pub shapes: ShapeConfig,
}

impl SimConfig {
    /// The gripper as grasp sources see it: the robot's stroke and finger width, the dataset's
    /// finger reach, clearance and friction.
    pub fn grasp_spec(&self) -> GraspSpec {
        GraspSpec {
            max_opening_m: self.robot.gripper.stroke_m,
            finger_width_m: self.robot.gripper.finger_width_m,
            ..GraspSpec::default()
        }
    }
}
