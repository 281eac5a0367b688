//! Grasping: what proposes grasps, one honestly judged attempt, and a grasp tried by the gripper alone.

pub mod attempt;
pub mod free_grasp;
pub mod proposals;
pub mod source;
