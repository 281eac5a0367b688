//! One grasp attempt, honestly judged: a top-down grasp from a grasp source becomes arm motions,
//! and the outcome is read from the physics afterwards.
//!
//! The attempt ([`execute`]), after [`plan_grasp`] turned a [`crate::perception::WorldGrasp`] into
//! a [`GraspPlan`]:
//! 1. IK to a pre-grasp pose above the grasp at a safe height (clear of everything the close-up
//!    saw), a timed joint move there, the gripper opening meanwhile to the predicted opening plus
//!    a margin (never beyond the stroke);
//! 2. a straight-line descent with stop-on-contact (a guarded move) to the grasp height: the
//!    fingertips [`AttemptConfig::grasp_depth_m`] below the surface at the grasp centre, but
//!    above the table and above whatever the depth image shows under the open fingers' lanes
//!    and the palm;
//! 3. close until the pads stall (or meet), squeeze for [`AttemptConfig::squeeze_s`];
//! 4. lift [`AttemptConfig::lift_height_m`] straight up, then hold [`AttemptConfig::hold_s`] —
//!    and **judge the grasp**;
//! 5. carry to the target basket at [`AttemptConfig::carry_height_m`] (≤ ~1.03 m: the arm's
//!    reach there), lower to just above the basket floor, open, back off, let the scene settle
//!    — and **judge the placement**.
//!
//! **Grasp success** (issue 14; stricter than the paper): after the lift the object's centre of
//! mass is at least [`AttemptConfig::success_rise_m`] above where it rested, stays there through
//! the hold, both fingers push on it at the end, the fingers are not closed on nothing, and the gap
//! is at least the object's width between the pads minus [`AttemptConfig::width_tolerance_m`] (the
//! width is the gap plus how deep the pads are sunk into the object's collider, found by ray casts
//! from the pads' outer faces: a pad sunk more than that holds the object by a physics artefact,
//! not by friction). The paper's **contact-only** criterion — exactly one object touches the pads
//! after the lift — is recorded beside it. **Placement success**: the object's centre of mass ends
//! at rest inside the target basket ([`crate::physics::config::BasketConfig::inner_bounds_m`]).
//!
//! Every failed attempt gets one [`FailureReason`]. Nothing is ever attached, welded or
//! teleported while the robot acts.
//!
//! Wall-clock times are kept apart from everything else ([`crate::timing::WallTimes`]), so that the
//! rest of a record is the same, bit for bit, for the same seed.

mod config;
mod execute;
mod motion;
mod plan;
mod verdict;

pub use config::{AttemptConfig, AttemptError};
pub use execute::{
    CARRY_INSET_M, Execution, Measurements, REST_DRIFT_M, REST_TURN_RAD, REST_WINDOW_S, execute,
};
pub use motion::{Cell, DETOUR_STEP_M, park};
pub use plan::{GraspPlan, plan_grasp, plan_grasp_for};
pub use verdict::{FailureReason, width_between_pads_m};
pub(crate) use verdict::{grasp_verdict, pinched_objects, touches_for_real, touching_objects};
