//! The work cell ([`Cell`]: the world, the robot in it, its IK) and how it moves: timed joint
//! moves and straight tool moves, guarded or not, holds, and the way back to the ready pose
//! ([`park`]). Every step is timed into the attempt's [`WallTimes`].

use nalgebra::{Isometry3, Translation3, Vector3};

use crate::physics::world::World;
use crate::robot::arm::Joints;
use crate::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp, top_down_rotation};
use crate::robot::trajectory::{JointTrajectory, LinearMove, MotionError, plan_linear_move};
use crate::robot::{ArmContact, Robot, RobotConfig};
use crate::timing::{WallTimes, Work};

use super::config::{AttemptConfig, AttemptError};
use super::verdict::touches_for_real;

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
    /// What the arm's links touched that they should not (the scenery, each other) in the
    /// moves since this was last emptied, each contact once ([`Robot::arm_contacts_at`] every
    /// [`ARM_CHECK_STEPS`] steps of a move); an attempt takes them into its record.
    pub arm_contacts: Vec<ArmContact>,
}

/// Steps between two checks of the arm's links against the scenery and each other while it
/// moves (default 4: every 17 ms at 240 Hz, about 2 mm of tool travel at the carry's speed).
pub const ARM_CHECK_STEPS: u32 = 4;

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
            arm_contacts: Vec::new(),
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
            arm_contacts: Vec::new(),
        })
    }

    /// Height of the table top (m).
    pub fn table_top_m(&self) -> f64 {
        f64::from(self.world.config().table.top_z_m())
    }
}

/// Steps a trajectory, guarded or not, recording arm-object contacts.
pub(super) struct Motion {
    pub(super) stopped_by_contact: bool,
    pub(super) arm_collision: bool,
}

pub(super) fn follow(
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
            if k % ARM_CHECK_STEPS == 0 || k == steps {
                let q = cell.robot.joints_rad();
                for contact in cell.robot.arm_contacts_at(&cell.world, &q) {
                    if !cell.arm_contacts.contains(&contact) {
                        cell.arm_contacts.push(contact);
                    }
                }
            }
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

pub(super) fn hold(
    cell: &mut Cell,
    seconds: f64,
    wall: &mut WallTimes,
) -> Result<(), AttemptError> {
    let steps = (seconds / f64::from(cell.world.dt_s())).round() as u32;
    wall.time(Work::Physics, || cell.robot.hold(&mut cell.world, steps))?;
    Ok(())
}

/// Steps until the opening command settled (or `timeout_s`).
pub(super) fn settle_opening(
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
pub(super) fn plan_joint_move(
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
pub(super) fn plan_straight(
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
pub(super) fn plan_straight_top_down(
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

/// Backs the gripper off (opens it fully, rises straight up to the pre-grasp height `up_to_z_m`
/// when it is lower) and returns to the ready pose — in one joint move to the ready joints when
/// the tool along it stays no lower than its two ends (`joint_move_not_below_ends`; from the
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
