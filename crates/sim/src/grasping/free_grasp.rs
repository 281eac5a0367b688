//! A grasp tried with the gripper alone, as Dex-Net and VGN label their data: the palm appears open
//! over the grasp at the plan's pre-grasp height, descends straight (guarded, as the arm's
//! descent), closes and squeezes, lifts straight up, holds, and is judged by the robot's own
//! criterion ([`crate::grasping::attempt`]'s verdict); then it is taken out of the world. No arm,
//! no carry: a fraction of an arm attempt's physics, and the label is whether the grasp holds.
//! `lgdm sim grasp-data` ([`crate::datagen::grasp_data`]) labels its rectangles so.
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_sim::grasping::attempt::AttemptConfig;
//! use lgdm_sim::grasping::free_grasp::{try_grasp, FreeGrasp};
//! use lgdm_sim::robot::gripper::GripperConfig;
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let top = world.config().table.top_z_m();
//! let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [200, 40, 40]);
//! let cube = world
//!     .spawn_object("cube", &cube, &lgdm_pointcloud::math::translation([0.0, -0.55, top]))
//!     .unwrap();
//! world.settle();
//! let top = f64::from(top);
//! let across = FreeGrasp { tcp_m: [0.0, -0.55, top + 0.03], yaw_rad: 0.0, opening_m: 0.08,
//!                          pregrasp_z_m: top + 0.15 };
//! let trial = try_grasp(&mut world, &GripperConfig::default(), &across, Some(cube),
//!                       &AttemptConfig::default()).unwrap();
//! assert!(trial.success, "{trial:?}");
//! ```

use serde::{Deserialize, Serialize};

use crate::grasping::attempt::{
    AttemptConfig, AttemptError, FailureReason, GraspPlan, Measurements, grasp_verdict,
    pinched_objects, touches_for_real, touching_objects, width_between_pads_m,
};
use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::world::World;
use crate::robot::gripper::{Gripper, GripperConfig, PalmPath, top_down_palm_pose};

/// Where a free gripper grasps: its tool centre at the grasp, the jaw's yaw, the opening it
/// descends with and the height it starts at (m, world).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FreeGrasp {
    /// Tool centre (between the pads) at the grasp.
    pub tcp_m: [f64; 3],
    /// Direction of the opening axis about world z (rad).
    pub yaw_rad: f64,
    /// Opening during the descent.
    pub opening_m: f64,
    /// Tool z where the descent starts.
    pub pregrasp_z_m: f64,
}

impl From<&GraspPlan> for FreeGrasp {
    /// The plan the robot would execute: its tool targets, opening and pre-grasp height.
    fn from(plan: &GraspPlan) -> Self {
        Self {
            tcp_m: plan.tcp_m,
            yaw_rad: plan.grasp.yaw_rad,
            opening_m: plan.opening_m,
            pregrasp_z_m: plan.pregrasp_z_m,
        }
    }
}

/// What a free gripper's trial found.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct FreeTrial {
    /// The grasp held by the robot's criterion.
    pub success: bool,
    /// The paper's criterion: exactly one object touches the pads after the lift.
    pub contact_only_success: bool,
    /// Why it failed: `collision_on_approach`, `missed` or `slipped_during_lift`.
    pub reason: Option<FailureReason>,
    /// The object judged (the one pinched, else `target`).
    #[serde(skip)]
    pub judged: Option<ObjectHandle>,
    /// Measurements along the way (the arm's fields stay unset).
    pub measured: Measurements,
    /// World steps the trial took.
    pub steps: u64,
}

/// Tries `grasp` with a free gripper of `gripper` in `world` (see the module docs). `target` is
/// the object aimed at, judged when nothing was pinched. The gripper is removed at the end; the
/// objects stay where the trial left them.
pub fn try_grasp(
    world: &mut World,
    gripper: &GripperConfig,
    grasp: &FreeGrasp,
    target: Option<ObjectHandle>,
    config: &AttemptConfig,
) -> Result<FreeTrial, AttemptError> {
    let rest: Vec<(ObjectHandle, f32)> = world
        .objects()
        .map(|h| Ok((h, world.object_center_of_mass_m(h)?[2])))
        .collect::<Result<_, WorldError>>()?;
    let [x, y, _] = grasp.tcp_m;
    let start = top_down_palm_pose([x, y, grasp.pregrasp_z_m], grasp.yaw_rad);
    let mut g = Gripper::new(world, gripper.clone(), &start, grasp.opening_m as f32)?;
    let first_step = world.steps();
    let trial = run(world, &mut g, grasp, target, &rest, config);
    g.remove(world);
    let mut trial = trial?;
    trial.steps = world.steps() - first_step;
    Ok(trial)
}

/// Steps the gripper along `path` from its start; with `guarded`, stops at the first real
/// touch. Returns whether it stopped so.
fn follow(
    world: &mut World,
    g: &mut Gripper,
    path: &PalmPath,
    guarded: bool,
) -> Result<bool, WorldError> {
    let dt = f64::from(world.dt_s());
    let duration = path.duration_s();
    let steps = (duration / dt).ceil().max(0.0) as u32;
    for k in 1..=steps {
        let t = (f64::from(k) * dt).min(duration);
        g.set_palm_pose(&path.pose_at(t))?;
        g.step(world);
        if guarded && touches_for_real(world, g) {
            return Ok(true);
        }
    }
    Ok(false)
}

fn steps_for(world: &World, seconds: f64) -> u32 {
    (seconds / f64::from(world.dt_s())).round() as u32
}

fn run(
    world: &mut World,
    g: &mut Gripper,
    grasp: &FreeGrasp,
    target: Option<ObjectHandle>,
    rest: &[(ObjectHandle, f32)],
    config: &AttemptConfig,
) -> Result<FreeTrial, AttemptError> {
    let mut out = FreeTrial::default();
    let [x, y, z] = grasp.tcp_m;
    // The descent, guarded as the arm's.
    let start = g.commanded_palm_pose();
    let at = top_down_palm_pose([x, y, z], grasp.yaw_rad);
    let path = PalmPath::new(
        &start,
        &at,
        config.descent.speed_m_s,
        config.descent.accel_m_s2,
    )?;
    let stopped = follow(world, g, &path, true)?;
    let reached = g.commanded_palm_pose();
    let reached_z = reached.translation.vector.z;
    let m = &mut out.measured;
    m.descent_stopped = stopped;
    m.descent_stop_above_plan_m = if stopped {
        (reached_z - z).max(0.0)
    } else {
        0.0
    };
    let collided = m.descent_stop_above_plan_m > config.early_stop_m;
    // Close and squeeze.
    g.set_opening(0.0)?;
    for _ in 0..steps_for(world, config.close_timeout_s).max(1) {
        if g.opening_settled() {
            break;
        }
        g.step(world);
    }
    for _ in 0..steps_for(world, config.squeeze_s) {
        g.step(world);
    }
    let gap = g.finger_gap_m(world);
    m.gap_after_close_m = Some(gap);
    let pinched = pinched_objects(world, g);
    m.pinched_after_close = pinched.len() == 1 && gap >= g.config().closed_gap_m;
    let judged = if pinched.len() == 1 {
        Some(pinched[0])
    } else {
        pinched.first().copied().or(target)
    };
    out.judged = judged;
    // Lift straight up from where the descent stopped.
    let mut lifted = reached;
    lifted.translation.vector.z += config.lift_height_m;
    let path = PalmPath::new(
        &reached,
        &lifted,
        config.lift.speed_m_s,
        config.lift.accel_m_s2,
    )?;
    follow(world, g, &path, false)?;
    let touching = touching_objects(world, g);
    out.measured.objects_touching_after_lift = touching.len();
    out.contact_only_success = touching.len() == 1;
    // Hold, then judge.
    let Some(object) = judged else {
        out.reason = Some(if collided {
            FailureReason::CollisionOnApproach
        } else {
            FailureReason::Missed
        });
        return Ok(out);
    };
    let rest_z = rest
        .iter()
        .find(|(o, _)| *o == object)
        .map_or(f32::NAN, |(_, z)| *z);
    let rise = |world: &World| -> Result<f32, WorldError> {
        Ok(world.object_center_of_mass_m(object)?[2] - rest_z)
    };
    out.measured.rise_after_lift_m = Some(rise(world)?);
    let mut min_rise = rise(world)?;
    for _ in 0..steps_for(world, config.hold_s) {
        g.step(world);
        min_rise = min_rise.min(rise(world)?);
    }
    world.check_finite()?;
    out.measured.min_rise_during_hold_m = Some(min_rise);
    let reading = g.grip_reading(world, object)?;
    out.measured.gap_after_hold_m = Some(reading.gap_m);
    let width = width_between_pads_m(world, g, object)?;
    out.measured.width_between_pads_m = width;
    let verdict = grasp_verdict(
        min_rise,
        &reading,
        width,
        out.measured.pinched_after_close,
        collided,
        config,
    );
    out.success = verdict.is_ok();
    out.reason = verdict.err();
    Ok(out)
}
