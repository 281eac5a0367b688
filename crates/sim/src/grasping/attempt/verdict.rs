//! Contacts and the verdict: what the pads touch and pinch (each push checked with parry's exact
//! distance), the object's width between the pads, the grasp criterion both the arm and the free
//! gripper are judged by, and why an attempt failed ([`FailureReason`]).

use nalgebra::{Point3, Vector3};
use rapier3d::parry::query::Ray;
use serde::{Deserialize, Serialize};

use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::RVec;
use crate::physics::world::World;
use crate::robot::gripper::{Contactee, GripReading, Gripper, GripperPart};

use super::config::AttemptConfig;

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
    /// A move the attempt needed would have brought an arm link into the scenery (the table, a
    /// basket, the pedestal, the floor) or into another link, and no lifted detour was clear:
    /// the move was turned down before it was made
    /// (`Measurements::avoided_contacts` says what it would have touched).
    ArmCollision,
    /// The fingers closed without pinching the object.
    Missed,
    /// The object was pinched but did not rise with the gripper or fell during the hold.
    SlippedDuringLift,
    /// The object was lifted but lost on the way to the basket.
    SlippedDuringCarry,
    /// The object was released and came to rest outside the basket (or is still falling
    /// there).
    DroppedOutside,
    /// The object was released inside the basket but did not come to rest there: it still
    /// rolled or rocked when the placement was judged
    /// ([`crate::grasping::attempt::REST_WINDOW_S`]).
    StillMoving,
    /// Packing only (judged by [`crate::tasks::packing::judge`], never by
    /// [`crate::grasping::attempt::execute()`]): the object was placed, but in the basket of a
    /// category that is not its own.
    Misrecognised,
}

impl FailureReason {
    /// Every reason, in a fixed order.
    pub const ALL: [FailureReason; 11] = [
        Self::NoGraspFound,
        Self::WiderThanGripper,
        Self::Unreachable,
        Self::CollisionOnApproach,
        Self::ArmCollision,
        Self::Missed,
        Self::SlippedDuringLift,
        Self::SlippedDuringCarry,
        Self::DroppedOutside,
        Self::StillMoving,
        Self::Misrecognised,
    ];

    /// The snake_case name (as in results.json).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::NoGraspFound => "no_grasp_found",
            Self::WiderThanGripper => "wider_than_gripper",
            Self::Unreachable => "unreachable",
            Self::CollisionOnApproach => "collision_on_approach",
            Self::ArmCollision => "arm_collision",
            Self::Missed => "missed",
            Self::SlippedDuringLift => "slipped_during_lift",
            Self::SlippedDuringCarry => "slipped_during_carry",
            Self::DroppedOutside => "dropped_outside",
            Self::StillMoving => "still_moving",
            Self::Misrecognised => "misrecognised",
        }
    }
}

impl std::fmt::Display for FailureReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
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
