//! From an object-centred crop to a judged grasp: what proposes grasps ([`source`]; [`rim`], the
//! rim proposals of `lgdm sim grasp-data`), how the robot asks for them and checks them
//! ([`proposals`]), one attempt of the arm ([`attempt`]), and a grasp tried by the gripper alone
//! ([`free_grasp`]); the round's memory of grasps that failed ([`failed`]). On physics, robot and
//! perception.

pub mod attempt;
pub mod failed;
pub mod free_grasp;
pub mod proposals;
pub mod rim;
pub mod source;
