//! How an attempt moves and how it is judged: [`AttemptConfig`], every constant with its
//! default, checked once; and [`AttemptError`], what aborts an attempt (a failed grasp is not an
//! error but a [`crate::grasping::attempt::FailureReason`]).

use lgdm_pointcloud::grasp::decode::GraspDecodeParams;
use serde::{Deserialize, Serialize};

use crate::physics::error::WorldError;
use crate::robot::RobotError;
use crate::robot::ik::IkError;
use crate::robot::trajectory::LinearMove;

use crate::grasping::source::ProposalCheck;

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
    /// ([`crate::grasping::attempt::GraspPlan::reaches_contacts`]).
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
    /// ([`crate::grasping::attempt::CARRY_INSET_M`]); before, it swept through the wall and fell.
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
    /// How a source's proposals are checked against the close-up's depth before the robot plans
    /// them (default: unset, the source's own default,
    /// [`crate::grasping::source::GraspSource::proposal_check`] — `contacts`, only the planner's
    /// check that both pads close on something
    /// ([`crate::grasping::attempt::GraspPlan::reaches_contacts`], which every plan gets whatever
    /// this says), for all but the network). A run's results record the check it used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proposal_check: Option<ProposalCheck>,
    /// When the check refuses every proposal for the full stroke, ask the source once more
    /// for [`crate::grasping::proposals::WIDEN_POOL`] times as many, decoded with half the quality
    /// threshold and half the peak distance, before the refused ones are tried (`refine-first`
    /// and `refine-ranked`) or a narrower opening is asked for (default: false; no effect
    /// with `contacts`).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub widen_when_refused: bool,
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

/// Errors that abort an attempt (not failures of the grasp: those are
/// [`crate::grasping::attempt::FailureReason`]s).
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
