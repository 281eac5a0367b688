//! One grasp attempt, honestly judged: a top-down grasp from a grasp source becomes arm motions,
//! and the outcome is read from the physics afterwards.
//!
//! The attempt ([`execute`]), after [`plan_grasp`] turned a [`WorldGrasp`] into a [`GraspPlan`]:
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
//! mass is at least [`AttemptConfig::success_rise_m`] above where it rested, stays there
//! through the hold, both fingers push on it at the end, the fingers are not closed on nothing,
//! and the gap is at least the object's width between the pads minus
//! [`AttemptConfig::width_tolerance_m`] (the width is the gap plus how deep the pads are sunk
//! into the object's collider, found by ray casts from the pads' outer faces: a pad sunk more
//! than that holds the object by a physics artefact, not by friction). The paper's **contact-only** criterion — exactly
//! one object touches the pads after the lift — is recorded beside it. **Placement success**:
//! the object's centre of mass ends at rest inside the target basket
//! ([`crate::physics::world::BasketConfig::inner_bounds_m`]).
//!
//! Every failed attempt gets one [`FailureReason`]. Nothing is ever attached, welded or
//! teleported while the robot acts.
//!
//! Wall-clock times are kept apart from everything else ([`WallTimes`]), so that the rest of a
//! record is the same, bit for bit, for the same seed.

use lgdm_pointcloud::grasp::decode::GraspDecodeParams;
use lgdm_pointcloud::math::transform_point;
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rapier3d::parry::query::Ray;
use serde::{Deserialize, Serialize};

use crate::perception::{ObjectView, WorldGrasp};
use crate::physics::world::{BasketConfig, ObjectHandle, RVec, World, WorldError};
use crate::robot::arm::Joints;
use crate::robot::gripper::{Contactee, GripReading, Gripper, GripperConfig, GripperPart};
use crate::robot::ik::{IkConfig, IkError, IkSolver, IkTarget, TopDownGrasp, top_down_rotation};
use crate::robot::trajectory::{JointTrajectory, LinearMove, MotionError, plan_linear_move};
use crate::robot::{Robot, RobotConfig, RobotError};
use crate::timing::{WallTimes, Work};

/// How an attempt moves and how it is judged. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttemptConfig {
    /// The fingertips reach at least this high above the table before descending: the
    /// pre-grasp height (m; default 0.25), raised to clear the tallest point the close-up saw
    /// by [`AttemptConfig::approach_clearance_m`].
    pub approach_height_m: f64,
    /// Clearance of the fingertips over the tallest visible point at the pre-grasp (m;
    /// default 0.05).
    pub approach_clearance_m: f64,
    /// The straight descent (default 0.15 m/s, 0.5 m/s², 1 cm IK waypoints).
    pub descent: LinearMove,
    /// The straight lift and the lowering into the basket (default 0.15 m/s, 0.5 m/s², 1 cm
    /// IK waypoints).
    pub lift: LinearMove,
    /// Added to the predicted opening before descending (m; default 0.02: 1 cm per side); the
    /// commanded opening never exceeds the stroke.
    pub opening_margin_m: f64,
    /// Fingertips go this far below the grasp's surface point (m; default 0.04 of the 0.05 m
    /// pads).
    pub grasp_depth_m: f64,
    /// Fingertips stay this far above the table (m; default 0.005).
    pub min_tip_height_m: f64,
    /// Fingertips stay this far above the highest surface the depth image shows in the open
    /// fingers' lanes (m; default 0.003).
    pub lane_clearance_m: f64,
    /// A grasp is tried only when the fingertips reach at least this far below the highest
    /// surface on each pad's half of the closing line (m; default 0.002): a plan whose tips the
    /// clearances above raised over what lies between the pads would close on air
    /// ([`GraspPlan::reaches_contacts`]).
    pub pad_overlap_m: f64,
    /// The palm's underside stays this far above the highest surface under it (m; default
    /// 0.005).
    pub palm_clearance_m: f64,
    /// Give up closing after this long (s; default 2).
    pub close_timeout_s: f64,
    /// Squeeze after the pads stalled before lifting (s; default 0.2).
    pub squeeze_s: f64,
    /// The lift (m; default 0.2).
    pub lift_height_m: f64,
    /// Grasp success: the object's centre of mass rose at least this much (m; default 0.10).
    pub success_rise_m: f32,
    /// …and stayed that high for this long after the lift (s; default 0.5).
    pub hold_s: f64,
    /// …with a gap no narrower than the object's width between the pads minus this (m;
    /// default 0.005).
    pub width_tolerance_m: f32,
    /// A guarded descent that stops this far above the planned grasp height counts as a
    /// collision on approach when the grasp then fails (m; default 0.01).
    pub early_stop_m: f64,
    /// Where the tool waits, pointing down, between attempts and when a round starts (m;
    /// default (0.05, −0.52, 1.25): the reference approach height above the drop region, 11 cm
    /// above the top of the tallest library object). Every approach is a straight line from
    /// here down to the pre-grasp, so the fingers never sweep through an object on the way (a
    /// joint move from a lower home toppled standing cereal boxes); a retreat is a joint move
    /// only when the tool along it stays no lower than its two ends, as the line's would.
    pub ready_position_m: [f64; 3],
    /// Straight moves between the ready pose and a pre-grasp (default 0.5 m/s, 1 m/s², IK
    /// waypoints every 1 cm).
    pub transit: LinearMove,
    /// Height of the tool over the baskets while carrying (m; default 1.03: the arm reaches
    /// the baskets up to ~1.035 m).
    pub carry_height_m: f64,
    /// While carrying, the held object's lowest point stays this far above the basket's walls
    /// and the table (m; default 0.03). An object hanging below the carry height's reach —
    /// a cereal box or a bottle held near its top — is carried to a point inside the basket
    /// nearer the arm, high enough to clear the near wall, and lowered there
    /// ([`CARRY_INSET_M`]); before, it swept through the wall and fell.
    pub carry_clearance_m: f64,
    /// The carry's joint speed and acceleration limits as a fraction of the arm's (default
    /// 1.0: the arm's full limits; speeds scale by it, accelerations by its square). In (0, 1].
    pub carry_speed_scale: f64,
    /// Narrower openings to plan for when the stroke found no grasp (m, tried in order; each
    /// one at least as wide as the stroke is skipped; default [0.085]). The analytic source
    /// checks the fingers' lanes as if they descended fully open, so a long stroke (the
    /// 2F-140's 140 mm) rules out grasps — a glass's rim — that the commanded opening (the
    /// grasp's width plus `opening_margin_m`) leaves room for; planning again for 85 mm finds
    /// them. The 2F-85 never uses it.
    pub fallback_openings_m: Vec<f32>,
    /// Index of the target basket in the world's baskets (default 0, the reference tray at
    /// (0.7, 0, 0.685)).
    pub target_basket: usize,
    /// Release with the object's lowest point this far above the basket floor (m; default
    /// 0.03).
    pub release_clearance_m: f64,
    /// Wait after the fingers opened before backing off (s; default 0.3).
    pub release_wait_s: f64,
    /// After the release the scene settles for up to this many of the world's settles
    /// (`world.settle.max_steps` each) before the placement is judged (default 3, 12.5 s at
    /// most; in 1 to 3). A can or a vase set upright on the basket floor can still rock on its
    /// rim after one (4.2 s): on the paper's objects 10 of the 16 grasped objects judged
    /// "dropped outside" were such master chef cans, standing in the basket's middle.
    pub release_settles: u32,
    /// How crop grasps are placed in the world (the median depth of a 5×5 window by default)
    /// and how the network source decodes its maps (quality threshold, peak distance in the
    /// network's input pixels, smoothing; default: train_ae's decoding; the jaw and the count
    /// are the checkpoint's and the scenario's).
    pub decode: GraspDecodeParams,
    /// How a source's proposals are checked against the close-up's depth before the robot
    /// plans them (default: unset, the source's own default,
    /// [`crate::grasping::source::GraspSource::proposal_check`] — `contacts`, only the planner's check
    /// that both pads close on something ([`GraspPlan::reaches_contacts`], which every plan
    /// gets whatever this says), for all but the network). A run's results record the check
    /// it used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proposal_check: Option<ProposalCheck>,
    /// When the check refuses every proposal for the full stroke, ask the source once more
    /// for [`crate::run::runner::WIDEN_POOL`] times as many, decoded with half the quality
    /// threshold and half the peak distance, before the refused ones are tried (`refine-first`
    /// and `refine-ranked`) or a narrower opening is asked for (default: false; no effect
    /// with `contacts`).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub widen_when_refused: bool,
}

/// How a grasp source's proposals are checked against the close-up's depth before they are
/// planned ([`crate::run::runner::ranked_grasps`]); the planner's contact check
/// ([`GraspPlan::reaches_contacts`]) follows in every case. A proposal that fails is dropped
/// and the next one taken — never another source's grasp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProposalCheck {
    /// No check before planning (the planner's contact check only).
    #[default]
    Contacts,
    /// The analytic source's test at the proposal's own centre and axis
    /// ([`lgdm_pointcloud::grasp::analytic::check_proposals`]): fingers closing from the full
    /// opening meet material on both sides within the friction cone, both finger lanes clear,
    /// the jaw covered, the palm clear. A proposal that passes is tried as proposed.
    Antipodal,
    /// As `antipodal`, and a proposal that passes is moved to its contacts' midpoint, its axis
    /// squared to the contact walls and its opening set to the contacts' distance (the
    /// proposal chooses where and which way; the depth, how wide).
    Refine,
    /// As `refine`, but the proposals the check refuses are not dropped: they follow the
    /// refined ones, as proposed and in their order (the planner's contact check still applies).
    /// Where the depth test finds nothing (flat or thin objects the analytic source cannot
    /// grasp either) the proposals are tried as they are.
    #[serde(rename = "refine-first")]
    RefineFirst,
    /// As `refine-first`, but the proposals that pass are tried in the order of the analytic
    /// source's quality where they settled (safe grasps first; its stability term prefers
    /// centres near the object's centroid), the proposal's rank breaking ties: the network
    /// chooses where to look, the depth which of those places first.
    #[serde(rename = "refine-ranked")]
    RefineRanked,
}

impl ProposalCheck {
    /// The word the option and the config spell.
    pub fn word(self) -> &'static str {
        match self {
            ProposalCheck::Contacts => "contacts",
            ProposalCheck::Antipodal => "antipodal",
            ProposalCheck::Refine => "refine",
            ProposalCheck::RefineFirst => "refine-first",
            ProposalCheck::RefineRanked => "refine-ranked",
        }
    }
}

impl Default for AttemptConfig {
    fn default() -> Self {
        let moves = LinearMove {
            speed_m_s: 0.15,
            accel_m_s2: 0.5,
            waypoint_spacing_m: 0.01,
            ..LinearMove::default()
        };
        Self {
            approach_height_m: 0.25,
            approach_clearance_m: 0.05,
            descent: moves.clone(),
            lift: moves,
            opening_margin_m: 0.02,
            grasp_depth_m: 0.04,
            min_tip_height_m: 0.005,
            lane_clearance_m: 0.003,
            pad_overlap_m: 0.002,
            palm_clearance_m: 0.005,
            close_timeout_s: 2.0,
            squeeze_s: 0.2,
            lift_height_m: 0.2,
            success_rise_m: 0.10,
            hold_s: 0.5,
            width_tolerance_m: 0.005,
            early_stop_m: 0.01,
            ready_position_m: [0.05, -0.52, 1.25],
            transit: LinearMove {
                speed_m_s: 0.5,
                accel_m_s2: 1.0,
                waypoint_spacing_m: 0.01,
                ..LinearMove::default()
            },
            carry_height_m: 1.03,
            carry_clearance_m: 0.03,
            carry_speed_scale: 1.0,
            fallback_openings_m: vec![0.085],
            target_basket: 0,
            release_clearance_m: 0.03,
            release_wait_s: 0.3,
            release_settles: 3,
            decode: GraspDecodeParams::default(),
            proposal_check: None,
            widen_when_refused: false,
        }
    }
}

impl AttemptConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), AttemptError> {
        let bad = |field: &'static str, value: f64| {
            Err(AttemptError::InvalidConfig {
                field,
                reason: format!("{value} must be positive and finite"),
            })
        };
        for (field, value) in [
            ("approach_height_m", self.approach_height_m),
            ("close_timeout_s", self.close_timeout_s),
            ("lift_height_m", self.lift_height_m),
            ("success_rise_m", f64::from(self.success_rise_m)),
            ("carry_height_m", self.carry_height_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, value);
            }
        }
        if let Some(w) = self
            .fallback_openings_m
            .iter()
            .find(|w| !(w.is_finite() && **w > 0.0))
        {
            return Err(AttemptError::InvalidConfig {
                field: "fallback_openings_m",
                reason: format!("{w} must be positive and finite"),
            });
        }
        if self.fallback_openings_m.len() > 16 {
            return Err(AttemptError::InvalidConfig {
                field: "fallback_openings_m",
                reason: format!("{} openings: at most 16", self.fallback_openings_m.len()),
            });
        }
        if !(1..=3).contains(&self.release_settles) {
            return Err(AttemptError::InvalidConfig {
                field: "release_settles",
                reason: format!("{} is not in 1 to 3", self.release_settles),
            });
        }
        if !(self.carry_speed_scale > 0.0 && self.carry_speed_scale <= 1.0) {
            return Err(AttemptError::InvalidConfig {
                field: "carry_speed_scale",
                reason: format!("{} is not in (0, 1]", self.carry_speed_scale),
            });
        }
        for (field, value) in [
            ("approach_clearance_m", self.approach_clearance_m),
            ("opening_margin_m", self.opening_margin_m),
            ("grasp_depth_m", self.grasp_depth_m),
            ("min_tip_height_m", self.min_tip_height_m),
            ("lane_clearance_m", self.lane_clearance_m),
            ("pad_overlap_m", self.pad_overlap_m),
            ("palm_clearance_m", self.palm_clearance_m),
            ("squeeze_s", self.squeeze_s),
            ("hold_s", self.hold_s),
            ("width_tolerance_m", f64::from(self.width_tolerance_m)),
            ("early_stop_m", self.early_stop_m),
            ("release_clearance_m", self.release_clearance_m),
            ("release_wait_s", self.release_wait_s),
            ("carry_clearance_m", self.carry_clearance_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(AttemptError::InvalidConfig {
                    field,
                    reason: format!("{value} must be non-negative and finite"),
                });
            }
        }
        self.descent
            .validate()
            .map_err(|e| AttemptError::InvalidConfig {
                field: "descent",
                reason: e.to_string(),
            })?;
        self.lift
            .validate()
            .map_err(|e| AttemptError::InvalidConfig {
                field: "lift",
                reason: e.to_string(),
            })?;
        self.decode
            .validate()
            .map_err(|e| AttemptError::InvalidConfig {
                field: "decode",
                reason: e.to_string(),
            })?;
        Ok(())
    }
}

/// Why an attempt failed (one per failed attempt).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureReason {
    /// The source proposed no grasp that could be placed in the world.
    NoGraspFound,
    /// No grasp, and the object aimed at is solid and wider than the gripper's stroke whichever
    /// way the jaws turn: no top-down grasp can take it (a hollow object such as a bowl is
    /// never said to be, since a grasp can take its wall).
    WiderThanGripper,
    /// The arm cannot reach the pre-grasp, the grasp or the basket.
    Unreachable,
    /// The arm or the fingers hit something on the way down and the grasp then failed.
    CollisionOnApproach,
    /// The fingers closed without pinching the object.
    Missed,
    /// The object was pinched but did not rise with the gripper or fell during the hold.
    SlippedDuringLift,
    /// The object was lifted but lost on the way to the basket.
    SlippedDuringCarry,
    /// The object was released but did not come to rest inside the basket.
    DroppedOutside,
    /// Packing only (judged by [`crate::tasks::packing::judge`], never by [`execute`]): the object was
    /// placed, but in the basket of a category that is not its own.
    Misrecognised,
}

impl FailureReason {
    /// Every reason, in a fixed order.
    pub const ALL: [FailureReason; 9] = [
        Self::NoGraspFound,
        Self::WiderThanGripper,
        Self::Unreachable,
        Self::CollisionOnApproach,
        Self::Missed,
        Self::SlippedDuringLift,
        Self::SlippedDuringCarry,
        Self::DroppedOutside,
        Self::Misrecognised,
    ];

    /// The snake_case name (as in results.json).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NoGraspFound => "no_grasp_found",
            Self::WiderThanGripper => "wider_than_gripper",
            Self::Unreachable => "unreachable",
            Self::CollisionOnApproach => "collision_on_approach",
            Self::Missed => "missed",
            Self::SlippedDuringLift => "slipped_during_lift",
            Self::SlippedDuringCarry => "slipped_during_carry",
            Self::DroppedOutside => "dropped_outside",
            Self::Misrecognised => "misrecognised",
        }
    }
}

impl std::fmt::Display for FailureReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Errors that abort an attempt (not failures of the grasp: those are [`FailureReason`]s).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AttemptError {
    /// A bad [`AttemptConfig`] field.
    #[error("attempt config: {field}: {reason}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The world failed (a NaN state, an unknown object).
    #[error(transparent)]
    World(#[from] WorldError),
    /// The robot failed (a command outside the limits).
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The IK solver could not be built.
    #[error(transparent)]
    Ik(#[from] IkError),
}

/// The work cell: the world, the robot in it and its IK solver.
#[derive(Debug)]
pub struct Cell {
    /// The physics world.
    pub world: World,
    /// The robot.
    pub robot: Robot,
    /// IK for the robot's arm (reused between moves).
    pub ik: IkSolver,
    /// The joints of the ready pose, where [`park`] brings the arm back to (home for
    /// [`Cell::new`]).
    pub ready_rad: Joints,
}

impl Cell {
    /// Adds the robot (at its home posture, gripper fully open) to `world`.
    pub fn new(mut world: World, config: RobotConfig) -> Result<Self, AttemptError> {
        let home = config.arm.home_rad;
        let stroke = config.gripper.stroke_m;
        let robot = Robot::new(&mut world, config, &home, stroke)?;
        let ik = IkSolver::new(robot.arm().clone(), IkConfig::default())?;
        Ok(Self {
            world,
            robot,
            ik,
            ready_rad: home,
        })
    }

    /// Adds the robot to `world` with its tool at `config`'s ready pose (top-down, the jaw yaw
    /// closest to home's), gripper fully open.
    pub fn at_ready(
        mut world: World,
        robot: RobotConfig,
        config: &AttemptConfig,
    ) -> Result<Self, AttemptError> {
        let home = robot.arm.home_rad;
        let stroke = robot.gripper.stroke_m;
        let mut ik = IkSolver::new(robot.effective_arm(), IkConfig::default())?;
        let home_tool =
            ik.model()
                .world_from_tool(&home)
                .map_err(|e| AttemptError::InvalidConfig {
                    field: "robot.arm.home_rad",
                    reason: e.to_string(),
                })?;
        let yaw = jaw_yaw_rad(&home_tool);
        let target = IkTarget::TopDown(TopDownGrasp::new(config.ready_position_m, yaw));
        let ready = ik
            .solve(&target, &home)
            .map_err(|e| AttemptError::InvalidConfig {
                field: "ready_position_m",
                reason: format!("the arm cannot reach it pointing down: {e}"),
            })?
            .joints_rad;
        let robot = Robot::new(&mut world, robot, &ready, stroke)?;
        Ok(Self {
            world,
            robot,
            ik,
            ready_rad: ready,
        })
    }

    /// Height of the table top (m).
    pub fn table_top_m(&self) -> f64 {
        f64::from(self.world.config().table.top_z_m())
    }
}

/// A grasp turned into tool targets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspPlan {
    /// The grasp it came from.
    pub grasp: WorldGrasp,
    /// Tool centre (between the pads) at the grasp (m, world).
    pub tcp_m: [f64; 3],
    /// Tool z at the pre-grasp (m).
    pub pregrasp_z_m: f64,
    /// Commanded opening (m): predicted + margin, at most the stroke.
    pub opening_m: f64,
    /// Highest surface in the open fingers' lanes above the table (m; from the depth image).
    pub lane_height_m: f64,
    /// Highest surface under the palm above the table (m).
    pub palm_height_m: f64,
    /// Fingertip height above the table at the grasp (m).
    pub tip_height_m: f64,
    /// The lower of the two pads' highest surfaces above the table on their halves of the
    /// closing line, between the open pads and 2 mm to either side of the pads' width (m; from
    /// the depth image): what the pads can meet as they close.
    pub contact_height_m: f64,
}

impl GraspPlan {
    /// Whether both pads, as planned, close on something: the fingertips are at least
    /// [`AttemptConfig::pad_overlap_m`] below the highest surface on each pad's half of the
    /// closing line. The clearances that keep the fingers off a neighbour in their lanes or the
    /// palm off whatever is under it can raise the tips above the object between them (a pile,
    /// a low object beside a tall one); such a plan would close on air.
    pub fn reaches_contacts(&self, config: &AttemptConfig) -> bool {
        self.tip_height_m + config.pad_overlap_m <= self.contact_height_m
    }
}

/// Plans the tool targets of `grasp` seen in `view`: the commanded opening, the fingertip height
/// (see [`AttemptConfig`]) from the close-up's depth, the pre-grasp height.
pub fn plan_grasp(
    cell: &Cell,
    view: &ObjectView,
    grasp: &WorldGrasp,
    config: &AttemptConfig,
) -> GraspPlan {
    plan_grasp_for(
        cell.robot.gripper().config(),
        cell.table_top_m(),
        view,
        grasp,
        config,
    )
}

/// [`plan_grasp`] for gripper `g` over a table whose top is at `top` (m): what it needs of the
/// cell, so a gripper without an arm ([`crate::grasping::free_grasp`]) plans the same way.
pub fn plan_grasp_for(
    g: &GripperConfig,
    top: f64,
    view: &ObjectView,
    grasp: &WorldGrasp,
    config: &AttemptConfig,
) -> GraspPlan {
    let stroke = f64::from(g.stroke_m);
    let opening = (grasp.opening_m + config.opening_margin_m).clamp(0.0, stroke);
    let thickness = f64::from(g.finger_thickness_m);
    let half_width = 0.5 * f64::from(g.finger_width_m);
    let palm_half_len = f64::from(g.palm_half_length_m());
    let palm_half_width = f64::from(g.palm_half_width_m);
    let finger_len = f64::from(g.finger_length_m);
    let (s, c) = grasp.yaw_rad.sin_cos();
    let [gx, gy, gz] = grasp.position_m;
    // Heights (above the table) of every close-up pixel near the grasp, sorted into the open
    // fingers' lanes (2 mm wider than the pads) and the palm's footprint.
    let k = view.shot.camera.intrinsics;
    let world_from_camera = view.shot.camera.world_from_camera;
    let camera_from_world = world_from_camera.inverse();
    let centre = transform_point(&camera_from_world, grasp.position_m.map(|v| v as f32));
    let reach_m = (palm_half_len.max(0.5 * opening + thickness) + 0.01).hypot(palm_half_width);
    let (mut lane, mut palm, mut tallest) = (0.0f64, 0.0f64, 0.0f64);
    // Highest surface on each pad's half of the closing line (a < 0, a > 0).
    let mut halves = [0.0f64; 2];
    let depth = &view.shot.frame.depth_m;
    let (w, h) = (k.width as i64, k.height as i64);
    for d in depth.iter().filter(|d| d.is_finite() && **d > 0.0) {
        tallest = tallest.max(f64::from(view.crop.table_depth_m - d));
    }
    if let Some([u0, v0]) = k.project(centre) {
        let r_px = (reach_m * f64::from(k.fx) / f64::from(centre[2]).max(0.05)).ceil() as i64 + 2;
        let (u0, v0) = (u0.round() as i64, v0.round() as i64);
        for v in (v0 - r_px).max(0)..=(v0 + r_px).min(h - 1) {
            for u in (u0 - r_px).max(0)..=(u0 + r_px).min(w - 1) {
                let z = depth[(v * w + u) as usize];
                if !(z.is_finite() && z > 0.0) {
                    continue;
                }
                let p = transform_point(&world_from_camera, k.unproject(u as f32, v as f32, z));
                let (dx, dy) = (f64::from(p[0]) - gx, f64::from(p[1]) - gy);
                let a = dx * c + dy * s;
                let b = -dx * s + dy * c;
                let height = f64::from(p[2]) - top;
                if a.abs() >= 0.5 * opening - 0.001
                    && a.abs() <= 0.5 * opening + thickness + 0.002
                    && b.abs() <= half_width + 0.002
                {
                    lane = lane.max(height);
                }
                if a.abs() < 0.5 * opening && b.abs() <= half_width + 0.002 {
                    let half = &mut halves[usize::from(a > 0.0)];
                    *half = half.max(height);
                }
                if a.abs() <= palm_half_len && b.abs() <= palm_half_width {
                    palm = palm.max(height);
                }
            }
        }
    }
    let surface = gz - top;
    let tip = (surface - config.grasp_depth_m)
        .max(config.min_tip_height_m)
        .max(lane + config.lane_clearance_m)
        .max(palm + config.palm_clearance_m - finger_len);
    let tip_from_tcp = f64::from(g.tip_from_tcp_m());
    let pregrasp_tip = config
        .approach_height_m
        .max(tallest + config.approach_clearance_m)
        .max(tip + 0.02);
    GraspPlan {
        grasp: *grasp,
        tcp_m: [gx, gy, top + tip + tip_from_tcp],
        pregrasp_z_m: top + pregrasp_tip + tip_from_tcp,
        opening_m: opening,
        lane_height_m: lane,
        palm_height_m: palm,
        tip_height_m: tip,
        contact_height_m: halves[0].min(halves[1]),
    }
}

/// What happened in an attempt (deterministic; no wall times).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Execution {
    /// Grasp success by the strict criterion.
    pub grasp_success: bool,
    /// The paper's criterion: exactly one object touches the pads after the lift.
    pub contact_only_success: bool,
    /// The object came to rest inside the target basket.
    pub placement_success: bool,
    /// Why it failed, if it did (a grasp success that was not placed also has a reason).
    pub reason: Option<FailureReason>,
    /// The object the fingers pinched after closing, if exactly one.
    #[serde(skip)]
    pub pinched_object: Option<ObjectHandle>,
    /// Measurements along the way.
    pub measured: Measurements,
}

/// Numbers measured during an attempt (m unless named otherwise).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Measurements {
    /// The guarded descent stopped on a contact.
    pub descent_stopped: bool,
    /// How far above the planned grasp height it stopped (0 when it did not).
    pub descent_stop_above_plan_m: f64,
    /// An arm link pushed an object during the approach or the descent.
    pub arm_collision: bool,
    /// Gap between the pads after closing.
    pub gap_after_close_m: Option<f32>,
    /// Both fingers pushed on one object after closing.
    pub pinched_after_close: bool,
    /// Rise of the judged object's centre of mass at the end of the lift.
    pub rise_after_lift_m: Option<f32>,
    /// Lowest rise during the hold.
    pub min_rise_during_hold_m: Option<f32>,
    /// Gap after the hold.
    pub gap_after_hold_m: Option<f32>,
    /// The object's widest chord between the pads (collider, along the closing axis).
    pub width_between_pads_m: Option<f32>,
    /// Objects touching the pads after the lift (the paper's check needs exactly one).
    pub objects_touching_after_lift: usize,
    /// The object's centre of mass after the placement settled (m, world).
    pub placed_at_m: Option<[f32; 3]>,
    /// Its speed (m/s) and spin (rad/s) then.
    pub placed_motion: Option<[f32; 2]>,
    /// Its lowest collider point then (m, world).
    pub placed_lowest_z_m: Option<f32>,
}

/// How far inside the basket's wall the highest carry point may be, at the most, on the side
/// toward the arm (m): room for a held object's half width.
pub const CARRY_INSET_M: f64 = 0.06;

/// Points tried between the basket's centre and [`CARRY_INSET_M`] from its near wall.
const CARRY_VIA_STEPS: usize = 5;

/// Steps a trajectory, guarded or not, recording arm-object contacts.
struct Motion {
    stopped_by_contact: bool,
    arm_collision: bool,
}

fn follow(
    cell: &mut Cell,
    trajectory: &JointTrajectory,
    guarded: bool,
    wall: &mut WallTimes,
) -> Result<Motion, AttemptError> {
    wall.time(Work::Physics, || {
        let dt = f64::from(cell.world.dt_s());
        let duration = trajectory.duration_s();
        let steps = (duration / dt).ceil().max(0.0) as u32;
        let mut arm_collision = false;
        for k in 1..=steps {
            let t = (f64::from(k) * dt).min(duration);
            cell.robot.step_to(&mut cell.world, trajectory, t)?;
            arm_collision |= !cell.robot.arm_touches(&cell.world).is_empty();
            if guarded && touches_for_real(&cell.world, cell.robot.gripper()) {
                return Ok(Motion {
                    stopped_by_contact: true,
                    arm_collision,
                });
            }
        }
        Ok(Motion {
            stopped_by_contact: false,
            arm_collision,
        })
    })
}

fn hold(cell: &mut Cell, seconds: f64, wall: &mut WallTimes) -> Result<(), AttemptError> {
    let steps = (seconds / f64::from(cell.world.dt_s())).round() as u32;
    wall.time(Work::Physics, || cell.robot.hold(&mut cell.world, steps))?;
    Ok(())
}

/// Steps until the opening command settled (or `timeout_s`).
fn settle_opening(
    cell: &mut Cell,
    timeout_s: f64,
    wall: &mut WallTimes,
) -> Result<(), AttemptError> {
    let max = (timeout_s / f64::from(cell.world.dt_s())).ceil() as u32;
    wall.time(Work::Physics, || {
        for _ in 0..max {
            if cell.robot.gripper().opening_settled() {
                break;
            }
            cell.robot.step(&mut cell.world)?;
        }
        Ok::<_, AttemptError>(())
    })
}

/// A joint move to a top-down tool pose, or `None` when IK or the trajectory fails.
fn plan_joint_move(
    cell: &mut Cell,
    position_m: [f64; 3],
    yaw_rad: f64,
    speed_scale: f64,
    wall: &mut WallTimes,
) -> Option<JointTrajectory> {
    let q0 = cell.robot.joints_rad();
    wall.time(Work::Planning, || {
        let target = IkTarget::TopDown(TopDownGrasp::new(position_m, yaw_rad));
        let q = cell.ik.solve(&target, &q0).ok()?.joints_rad;
        if speed_scale == 1.0 {
            return JointTrajectory::point_to_point(cell.robot.arm(), &q0, &q).ok();
        }
        let mut arm = cell.robot.arm().clone();
        arm.max_speed_rad_s = arm.max_speed_rad_s.map(|v| v * speed_scale);
        arm.max_accel_rad_s2 = arm.max_accel_rad_s2.map(|a| a * speed_scale * speed_scale);
        JointTrajectory::point_to_point(&arm, &q0, &q).ok()
    })
}

/// Points along a joint move at which [`joint_move_not_below_ends`] checks the tool's height.
const JOINT_MOVE_CHECKS: usize = 50;

/// The joint move from the arm's joints to `goal`, when the tool along it (checked at
/// [`JOINT_MOVE_CHECKS`] evenly timed points) never comes more than a millimetre below the
/// lower of its two ends — as a straight line between them would not; else `None`.
fn joint_move_not_below_ends(
    cell: &Cell,
    goal: &Joints,
    wall: &mut WallTimes,
) -> Option<JointTrajectory> {
    let arm = cell.robot.arm();
    let q0 = cell.robot.joints_rad();
    wall.time(Work::Planning, || {
        let go = JointTrajectory::point_to_point(arm, &q0, goal).ok()?;
        let z = |q: &Joints| {
            arm.forward_unchecked(q)
                .world_from_tool
                .translation
                .vector
                .z
        };
        let (z0, z1) = (z(&q0), z(goal));
        let duration = go.duration_s();
        (1..JOINT_MOVE_CHECKS)
            .all(|k| {
                let f = k as f64 / JOINT_MOVE_CHECKS as f64;
                z(&go.sample(f * duration)) >= z0.min(z1) - 1e-3
            })
            .then_some(go)
    })
}

/// A straight tool move to the current orientation at `position_m`.
fn plan_straight(
    cell: &mut Cell,
    position_m: [f64; 3],
    params: &LinearMove,
    wall: &mut WallTimes,
) -> Result<JointTrajectory, MotionError> {
    let q0 = cell.robot.joints_rad();
    let mut goal = cell.robot.world_from_tool();
    goal.translation.vector = Vector3::from(position_m);
    wall.time(Work::Planning, || {
        plan_linear_move(&mut cell.ik, &q0, &goal, params)
    })
}

/// The jaw yaw of a top-down tool pose: the direction of the tool's x axis in the world's XY
/// plane (rad).
fn jaw_yaw_rad(world_from_tool: &Isometry3<f64>) -> f64 {
    let x = world_from_tool.rotation * Vector3::x();
    x.y.atan2(x.x)
}

/// A straight tool move to the top-down pose at `position_m` with jaw yaw `yaw_rad` — or
/// `yaw_rad` + π, whichever turns the wrist less (the jaw is symmetric).
fn plan_straight_top_down(
    cell: &mut Cell,
    position_m: [f64; 3],
    yaw_rad: f64,
    params: &LinearMove,
    wall: &mut WallTimes,
) -> Result<JointTrajectory, MotionError> {
    let q0 = cell.robot.joints_rad();
    let current = jaw_yaw_rad(&cell.robot.world_from_tool());
    let mut turn = (yaw_rad - current).rem_euclid(std::f64::consts::PI);
    if turn > std::f64::consts::FRAC_PI_2 {
        turn -= std::f64::consts::PI;
    }
    let goal = Isometry3::from_parts(
        Translation3::from(Vector3::from(position_m)),
        top_down_rotation(current + turn),
    );
    wall.time(Work::Planning, || {
        plan_linear_move(&mut cell.ik, &q0, &goal, params)
    })
}

/// Largest true distance (m) between a gripper part and what it pushes on for the push to count
/// as a touch in a guarded move.
const TOUCH_DISTANCE_M: f32 = 0.001;

/// Whether the palm or a finger pushes on anything now — on something really within
/// [`TOUCH_DISTANCE_M`]. rapier's polyhedron–cuboid manifolds can hold a ghost point: a
/// fingertip passing 4 mm beside a can's shoulder got a contact 0.5 mm "below" its tip plane
/// with a vertical normal and a 12 N push, so the descent stopped 3 cm early. Each pushing pair
/// is therefore checked with parry's exact distance between the two colliders.
pub(crate) fn touches_for_real(world: &World, gripper: &Gripper) -> bool {
    let physics = &world.physics;
    for (_, part) in gripper.part_colliders() {
        for pair in physics.narrow_phase.contact_pairs_with(part) {
            if !(pair.has_any_active_contact() && pair.total_impulse_magnitude() > 0.0) {
                continue;
            }
            let (Some(a), Some(b)) = (
                physics.colliders.get(pair.collider1),
                physics.colliders.get(pair.collider2),
            ) else {
                continue;
            };
            let close =
                rapier3d::parry::query::distance(a.position(), a.shape(), b.position(), b.shape())
                    .map_or(true, |d| d.distance <= TOUCH_DISTANCE_M);
            if close {
                return true;
            }
        }
    }
    false
}

/// Objects both of whose fingers push on them now, sorted.
pub(crate) fn pinched_objects(world: &World, gripper: &Gripper) -> Vec<ObjectHandle> {
    let touches = gripper.touches(world);
    let mut by_finger: [Vec<ObjectHandle>; 2] = [Vec::new(), Vec::new()];
    for t in &touches {
        if let Contactee::Object(h) = t.other {
            match t.part {
                GripperPart::Finger0 => by_finger[0].push(h),
                GripperPart::Finger1 => by_finger[1].push(h),
                GripperPart::Palm => {}
            }
        }
    }
    let mut out: Vec<ObjectHandle> = by_finger[0]
        .iter()
        .copied()
        .filter(|h| by_finger[1].contains(h))
        .collect();
    out.sort();
    out.dedup();
    out
}

/// Objects either finger (or the palm) touches now, sorted.
pub(crate) fn touching_objects(world: &World, gripper: &Gripper) -> Vec<ObjectHandle> {
    let mut out: Vec<ObjectHandle> = gripper
        .touches(world)
        .iter()
        .filter(|t| t.part != GripperPart::Palm)
        .filter_map(|t| match t.other {
            Contactee::Object(h) => Some(h),
            Contactee::Scenery => None,
        })
        .collect();
    out.sort();
    out.dedup();
    out
}

/// The object's width between the pads: the gap plus how deep each pad is sunk into the
/// object's collider, measured by ray casts from each pad's outer face toward the other pad at
/// 3 × 3 points of the pad area (a pad whose inner face rests on the surface is sunk 0). `None`
/// when no ray meets the object between the pads' outer faces. Works for compound colliders
/// (a rim pinched between the pads is as wide as the rim, not as the whole vessel).
pub fn width_between_pads_m(
    world: &World,
    gripper: &crate::robot::gripper::Gripper,
    object: ObjectHandle,
) -> Result<Option<f32>, WorldError> {
    let collider = &world.physics.colliders[world.object_collider(object)?];
    let shape = collider.shape();
    let pose = collider.position();
    let g = gripper.config();
    let palm = gripper.palm_pose(world);
    let [f0, f1] = gripper.finger_positions_in_palm_m(world);
    let t = g.finger_thickness_m;
    let gap = gripper.finger_gap_m(world);
    let x_axis = palm.rotation * Vector3::x();
    let dir = RVec::new(x_axis.x as f32, x_axis.y as f32, x_axis.z as f32);
    let reach = t + gap.max(0.0);
    let mut sunk = [None::<f32>; 2];
    for fy in [-0.45f64, 0.0, 0.45] {
        for fz in [-0.45f64, 0.0, 0.45] {
            let (y, z) = (
                fy * f64::from(g.finger_width_m),
                fz * f64::from(g.finger_length_m),
            );
            for (side, (outer_x, sign)) in [
                (f64::from(f0[0] - 0.5 * t), 1.0f32),
                (f64::from(f1[0] + 0.5 * t), -1.0f32),
            ]
            .into_iter()
            .enumerate()
            {
                let p = palm * Point3::new(outer_x, y, z);
                let origin = RVec::new(p.x as f32, p.y as f32, p.z as f32);
                if let Some(hit) = shape.cast_ray(pose, &Ray::new(origin, dir * sign), reach, true)
                {
                    let depth = (t - hit).max(0.0);
                    sunk[side] = Some(sunk[side].map_or(depth, |d: f32| d.max(depth)));
                }
            }
        }
    }
    Ok(match sunk {
        [None, None] => None,
        [a, b] => Some(gap + a.unwrap_or(0.0) + b.unwrap_or(0.0)),
    })
}

/// Runs one grasp attempt from the current state of `cell` (the arm parked, the gripper open):
/// approach, descend, close, lift, judge, carry, release, judge (one private function per
/// phase). `target` is the object the grasp aimed at (for judging when nothing was pinched);
/// every live object's resting centre-of-mass height is read at the start, for the rise. The
/// arm is left where the attempt ended; see [`park`].
pub fn execute(
    cell: &mut Cell,
    plan: &GraspPlan,
    target: Option<ObjectHandle>,
    config: &AttemptConfig,
    wall: &mut WallTimes,
) -> Result<Execution, AttemptError> {
    let rest: Vec<(ObjectHandle, f32)> = cell
        .world
        .objects()
        .map(|h| Ok((h, cell.world.object_center_of_mass_m(h)?[2])))
        .collect::<Result<_, WorldError>>()?;
    let mut attempt = Attempt {
        cell,
        plan,
        config,
        wall,
        out: Execution::default(),
    };
    match attempt.run(target, &rest) {
        Ok(()) => Ok(attempt.out),
        Err(Stop::Failed(reason)) => {
            attempt.out.reason = Some(reason);
            Ok(attempt.out)
        }
        Err(Stop::Error(e)) => Err(e),
    }
}

/// The grasp criterion after the hold (see the module docs): the judged object's centre of mass
/// stayed at least [`AttemptConfig::success_rise_m`] up (`min_rise`), both pads still push on it
/// (`reading`) and the gap between them is no narrower than its `width` between the pads, less
/// [`AttemptConfig::width_tolerance_m`]. A failure is `missed` (or `collision_on_approach`)
/// unless the pads pinched it after closing, then `slipped_during_lift`. One home for the arm's
/// attempts and the free gripper's ([`crate::grasping::free_grasp`]).
pub(crate) fn grasp_verdict(
    min_rise: f32,
    reading: &GripReading,
    width: Option<f32>,
    pinched_after_close: bool,
    collided: bool,
    config: &AttemptConfig,
) -> Result<(), FailureReason> {
    let wide_enough = width.is_none_or(|w| reading.gap_m >= w - config.width_tolerance_m);
    if min_rise >= config.success_rise_m && reading.pinching() && wide_enough {
        Ok(())
    } else if pinched_after_close {
        Err(FailureReason::SlippedDuringLift)
    } else if collided {
        Err(FailureReason::CollisionOnApproach)
    } else {
        Err(FailureReason::Missed)
    }
}

/// Why the phases of an attempt ended early: the grasp or the placement failed (the
/// [`Execution`] says how far it got), or an error aborts the attempt.
enum Stop {
    Failed(FailureReason),
    Error(AttemptError),
}

impl From<AttemptError> for Stop {
    fn from(e: AttemptError) -> Self {
        Self::Error(e)
    }
}

impl From<WorldError> for Stop {
    fn from(e: WorldError) -> Self {
        Self::Error(e.into())
    }
}

impl From<RobotError> for Stop {
    fn from(e: RobotError) -> Self {
        Self::Error(e.into())
    }
}

/// Where the guarded descent ended.
struct Descent {
    /// Tool height where the descent stopped (m).
    reached_z_m: f64,
    /// The arm touched an object, or the descent stopped early (see
    /// [`AttemptConfig::early_stop_m`]).
    collided: bool,
}

/// One attempt in progress: the phases of [`execute`] as methods, each adding its measurements
/// to `out`.
struct Attempt<'a> {
    cell: &'a mut Cell,
    plan: &'a GraspPlan,
    config: &'a AttemptConfig,
    wall: &'a mut WallTimes,
    out: Execution,
}

impl Attempt<'_> {
    /// The phases in order; `rest` holds every live object's resting centre-of-mass height.
    fn run(
        &mut self,
        target: Option<ObjectHandle>,
        rest: &[(ObjectHandle, f32)],
    ) -> Result<(), Stop> {
        self.approach()?;
        let descent = self.descend()?;
        let judged = self.close(target)?;
        self.lift(descent.reached_z_m)?;
        let object = self.judge_grasp(judged, descent.collided, rest)?;
        let (basket, at) = self.carry(object)?;
        self.release(at)?;
        self.judge_placement(object, &basket)
    }

    /// Phase 1, pre-grasp: a straight move down from the ready pose, opening meanwhile.
    fn approach(&mut self) -> Result<(), Stop> {
        let [x, y, _] = self.plan.tcp_m;
        self.cell
            .robot
            .gripper_mut()
            .set_opening(self.plan.opening_m as f32)?;
        let Ok(approach) = plan_straight_top_down(
            self.cell,
            [x, y, self.plan.pregrasp_z_m],
            self.plan.grasp.yaw_rad,
            &self.config.transit,
            self.wall,
        ) else {
            return Err(Stop::Failed(FailureReason::Unreachable));
        };
        let m = follow(self.cell, &approach, false, self.wall)?;
        self.out.measured.arm_collision |= m.arm_collision;
        settle_opening(self.cell, 1.0, self.wall)?;
        Ok(())
    }

    /// Phase 2: a guarded straight descent to the grasp height.
    fn descend(&mut self) -> Result<Descent, Stop> {
        let [x, y, z] = self.plan.tcp_m;
        let Ok(descent) = plan_straight(self.cell, [x, y, z], &self.config.descent, self.wall)
        else {
            return Err(Stop::Failed(FailureReason::Unreachable));
        };
        let m = follow(self.cell, &descent, true, self.wall)?;
        let measured = &mut self.out.measured;
        measured.arm_collision |= m.arm_collision;
        measured.descent_stopped = m.stopped_by_contact;
        let reached_z = self.cell.robot.world_from_tool().translation.vector.z;
        measured.descent_stop_above_plan_m = if m.stopped_by_contact {
            (reached_z - z).max(0.0)
        } else {
            0.0
        };
        let collided =
            measured.arm_collision || measured.descent_stop_above_plan_m > self.config.early_stop_m;
        Ok(Descent {
            reached_z_m: reached_z,
            collided,
        })
    }

    /// Phase 3: close and squeeze. Returns the object to judge: the one pinched, else the first
    /// of several pinched, else `target`.
    fn close(&mut self, target: Option<ObjectHandle>) -> Result<Option<ObjectHandle>, Stop> {
        let cell = &mut *self.cell;
        cell.robot.gripper_mut().set_opening(0.0)?;
        settle_opening(cell, self.config.close_timeout_s, self.wall)?;
        hold(cell, self.config.squeeze_s, self.wall)?;
        let gap = cell.robot.gripper().finger_gap_m(&cell.world);
        self.out.measured.gap_after_close_m = Some(gap);
        let closed_gap = cell.robot.gripper().config().closed_gap_m;
        let pinched = pinched_objects(&cell.world, cell.robot.gripper());
        self.out.measured.pinched_after_close = pinched.len() == 1 && gap >= closed_gap;
        let judged = if pinched.len() == 1 {
            Some(pinched[0])
        } else {
            pinched.first().copied().or(target)
        };
        if self.out.measured.pinched_after_close {
            self.out.pinched_object = judged;
        }
        Ok(judged)
    }

    /// Phase 4: lift straight up from where the descent stopped; count what touches the pads
    /// then (the paper's contact-only criterion).
    fn lift(&mut self, reached_z_m: f64) -> Result<(), Stop> {
        let [x, y, _] = self.plan.tcp_m;
        let lifted_z = reached_z_m + self.config.lift_height_m;
        let Ok(lift) = plan_straight(self.cell, [x, y, lifted_z], &self.config.lift, self.wall)
        else {
            return Err(Stop::Failed(FailureReason::Unreachable));
        };
        follow(self.cell, &lift, false, self.wall)?;
        let touching = touching_objects(&self.cell.world, self.cell.robot.gripper());
        self.out.measured.objects_touching_after_lift = touching.len();
        self.out.contact_only_success = touching.len() == 1;
        Ok(())
    }

    /// Phase 4: hold, then judge the grasp of `judged` (see the module docs). Returns the object
    /// held.
    fn judge_grasp(
        &mut self,
        judged: Option<ObjectHandle>,
        collided: bool,
        rest: &[(ObjectHandle, f32)],
    ) -> Result<ObjectHandle, Stop> {
        let missed = if collided {
            FailureReason::CollisionOnApproach
        } else {
            FailureReason::Missed
        };
        let Some(object) = judged else {
            return Err(Stop::Failed(missed));
        };
        let rest_z = rest.iter().find(|(o, _)| *o == object).map(|(_, z)| *z);
        let rise = |cell: &Cell| -> Result<f32, WorldError> {
            Ok(cell.world.object_center_of_mass_m(object)?[2] - rest_z.unwrap_or(f32::NAN))
        };
        let (config, out) = (self.config, &mut self.out);
        let cell = &mut *self.cell;
        out.measured.rise_after_lift_m = Some(rise(cell)?);
        let hold_steps = (config.hold_s / f64::from(cell.world.dt_s())).round() as u32;
        let mut min_rise = rise(cell)?;
        self.wall.time(Work::Physics, || {
            for _ in 0..hold_steps {
                cell.robot.step(&mut cell.world)?;
                min_rise = min_rise.min(rise(cell)?);
            }
            Ok::<_, AttemptError>(())
        })?;
        out.measured.min_rise_during_hold_m = Some(min_rise);
        let reading = cell.robot.gripper().grip_reading(&cell.world, object)?;
        out.measured.gap_after_hold_m = Some(reading.gap_m);
        let width = width_between_pads_m(&cell.world, cell.robot.gripper(), object)?;
        out.measured.width_between_pads_m = width;
        let verdict = grasp_verdict(
            min_rise,
            &reading,
            width,
            out.measured.pinched_after_close,
            collided,
            config,
        );
        out.grasp_success = verdict.is_ok();
        verdict.map_err(Stop::Failed)?;
        Ok(object)
    }

    /// Phase 5: carry `object` to the target basket at the carry height — or, when it hangs
    /// too low to clear the walls there, higher over a point nearer the arm
    /// ([`AttemptConfig::carry_clearance_m`]) — and lower it until its lowest collider point is
    /// just above the basket floor. Returns the basket and the (x, y) it was lowered at.
    fn carry(&mut self, object: ObjectHandle) -> Result<(BasketConfig, [f64; 2]), Stop> {
        let config = self.config;
        let baskets = &self.cell.world.config().baskets;
        let Some(basket) = baskets.get(config.target_basket).cloned() else {
            return Err(Stop::Error(AttemptError::InvalidConfig {
                field: "target_basket",
                reason: format!(
                    "basket {} of a world with {}",
                    config.target_basket,
                    baskets.len()
                ),
            }));
        };
        let [bx, by, floor_z] = basket.floor_center_m.map(f64::from);
        let yaw = self.plan.grasp.yaw_rad;
        let speed = config.carry_speed_scale;
        // How far the object hangs below the tool, and how high the tool must be for it to
        // clear the basket's walls and the table.
        let hang = self.below_tool_m(object)?.max(0.0);
        let clear_of = (floor_z + f64::from(basket.wall_height_m)).max(self.cell.table_top_m());
        let needed = clear_of + hang + config.carry_clearance_m;
        let mut carry = None;
        if needed > config.carry_height_m {
            // Over the basket's centre the arm cannot reach that high: try points inside the
            // basket nearer the arm's base, the first the arm reaches.
            let base = self.cell.robot.arm().world_from_base.translation_m;
            let (dx, dy) = (base[0] - bx, base[1] - by);
            let norm = dx.hypot(dy).max(1e-9);
            let inset =
                f64::from(0.5 * basket.inner_size_m[0].min(basket.inner_size_m[1])) - CARRY_INSET_M;
            for k in 0..=CARRY_VIA_STEPS {
                let off = inset * k as f64 / CARRY_VIA_STEPS as f64;
                let via = [bx + dx / norm * off, by + dy / norm * off, needed];
                if let Some(t) = plan_joint_move(self.cell, via, yaw, speed, self.wall) {
                    carry = Some((t, via));
                    break;
                }
            }
        }
        let (carry, at) = match carry {
            Some(found) => found,
            None => {
                let above = [bx, by, config.carry_height_m];
                let Some(t) = plan_joint_move(self.cell, above, yaw, speed, self.wall) else {
                    return Err(Stop::Failed(FailureReason::Unreachable));
                };
                (t, above)
            }
        };
        let [bx, by, _] = at;
        follow(self.cell, &carry, false, self.wall)?;
        if !still_holds(self.cell, object)? {
            return Err(Stop::Failed(FailureReason::SlippedDuringCarry));
        }
        // Lower until the object's lowest collider point is just above the basket floor.
        let tcp_z = self.cell.robot.world_from_tool().translation.vector.z;
        let below = self.below_tool_m(object)?;
        let release_z = (floor_z + below + config.release_clearance_m).min(tcp_z);
        if release_z < tcp_z - 1e-3
            && let Ok(lower) =
                plan_straight(self.cell, [bx, by, release_z], &config.lift, self.wall)
        {
            follow(self.cell, &lower, false, self.wall)?;
        }
        if !still_holds(self.cell, object)? {
            return Err(Stop::Failed(FailureReason::SlippedDuringCarry));
        }
        Ok((basket, [bx, by]))
    }

    /// How far `object`'s lowest collider point is below the tool centre now (m; negative when
    /// it is above, 0 when it has no collider points).
    fn below_tool_m(&self, object: ObjectHandle) -> Result<f64, Stop> {
        let tcp_z = self.cell.robot.world_from_tool().translation.vector.z;
        let pose = self.cell.world.object_pose(object)?;
        let lowest = self
            .cell
            .world
            .object_hull_points_m(object)?
            .iter()
            .map(|p| f64::from(transform_point(&pose, *p)[2]))
            .fold(f64::INFINITY, f64::min);
        Ok(if lowest.is_finite() {
            tcp_z - lowest
        } else {
            0.0
        })
    }

    /// Phase 5: open, wait, back off up to the carry height over `basket`, let the scene
    /// settle.
    fn release(&mut self, [bx, by]: [f64; 2]) -> Result<(), Stop> {
        let config = self.config;
        let stroke = self.cell.robot.gripper().config().stroke_m;
        self.cell.robot.gripper_mut().set_opening(stroke)?;
        settle_opening(self.cell, 2.0, self.wall)?;
        hold(self.cell, config.release_wait_s, self.wall)?;
        let up = [bx, by, config.carry_height_m];
        if let Ok(up) = plan_straight(self.cell, up, &config.lift, self.wall) {
            follow(self.cell, &up, false, self.wall)?;
        }
        let cell = &mut *self.cell;
        self.wall.time(Work::Physics, || {
            for _ in 0..config.release_settles {
                if cell.world.settle().settled {
                    break;
                }
            }
        });
        Ok(())
    }

    /// Phase 5: judge the placement: `object` at rest inside `basket`.
    fn judge_placement(&mut self, object: ObjectHandle, basket: &BasketConfig) -> Result<(), Stop> {
        let world = &self.cell.world;
        let out = &mut self.out;
        let com = world.object_center_of_mass_m(object)?;
        out.measured.placed_at_m = Some(com);
        // Inside: the centre of mass between the walls, resting on the floor (its lowest point
        // between the floor and the wall tops; a tall object's centre may stand above them).
        let (lo, hi) = basket.inner_bounds_m();
        let pose = world.object_pose(object)?;
        let lowest = world
            .object_hull_points_m(object)?
            .iter()
            .map(|p| transform_point(&pose, *p)[2])
            .fold(f32::INFINITY, f32::min);
        let lowest = if lowest.is_finite() { lowest } else { com[2] };
        let inside = (0..2).all(|i| com[i] > lo[i] && com[i] < hi[i])
            && lowest > lo[2] - 0.01
            && lowest < hi[2];
        let (v, w) = world.object_velocity(object)?;
        let speed = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        let spin = w.iter().map(|c| c * c).sum::<f32>().sqrt();
        let at_rest = speed < 0.02 && spin < 0.2;
        out.measured.placed_motion = Some([speed, spin]);
        out.measured.placed_lowest_z_m = Some(lowest);
        out.placement_success = inside && at_rest;
        if !out.placement_success {
            return Err(Stop::Failed(FailureReason::DroppedOutside));
        }
        Ok(())
    }
}

/// Whether both fingers still push on `object`.
fn still_holds(cell: &Cell, object: ObjectHandle) -> Result<bool, WorldError> {
    Ok(cell
        .robot
        .gripper()
        .grip_reading(&cell.world, object)?
        .pinching())
}

/// Backs the gripper off (opens it fully, rises straight up to the pre-grasp height `up_to_z_m`
/// when it is lower) and returns to the ready pose — in one joint move to the ready joints when
/// the tool along it stays no lower than its two ends ([`joint_move_not_below_ends`]; from the
/// baskets it does), else in a straight line — where frames are taken from and the next
/// approach starts.
pub fn park(
    cell: &mut Cell,
    up_to_z_m: f64,
    config: &AttemptConfig,
    wall: &mut WallTimes,
) -> Result<(), AttemptError> {
    let stroke = cell.robot.gripper().config().stroke_m;
    cell.robot.gripper_mut().set_opening(stroke)?;
    let tool = cell.robot.world_from_tool();
    let [x, y] = [tool.translation.vector.x, tool.translation.vector.y];
    if tool.translation.vector.z < up_to_z_m - 1e-3
        && let Ok(up) = plan_straight(cell, [x, y, up_to_z_m], &config.lift, wall)
    {
        follow(cell, &up, false, wall)?;
    }
    settle_opening(cell, 1.0, wall)?;
    // Straight to the ready joints when that joint move keeps the tool no lower than where it
    // is and where it goes, as the line would: from the reference basket it replaces the
    // line's joint-limited 4.3 s and the wrist's 1.7-second turn back with one 1.5–2 s move.
    if let Some(go) = joint_move_not_below_ends(cell, &{ cell.ready_rad }, wall) {
        follow(cell, &go, false, wall)?;
        return Ok(());
    }
    let yaw = jaw_yaw_rad(&cell.robot.world_from_tool());
    let ready = config.ready_position_m;
    let at = cell.robot.world_from_tool().translation.vector;
    if (at - Vector3::from(ready)).norm() > 1e-3
        && let Ok(back) = plan_straight_top_down(cell, ready, yaw, &config.transit, wall)
    {
        follow(cell, &back, false, wall)?;
    }
    // Then the ready joints exactly — at the ready point this only turns the wrist back — so
    // turns do not add up over the attempts of a round until the wrist reaches its limit.
    let q0 = cell.robot.joints_rad();
    let q_ready = cell.ready_rad;
    if q0 != q_ready {
        let arm = cell.robot.arm().clone();
        let go = wall.time(Work::Planning, || {
            JointTrajectory::point_to_point(&arm, &q0, &q_ready)
        });
        if let Ok(go) = go {
            follow(cell, &go, false, wall)?;
        }
    }
    Ok(())
}
