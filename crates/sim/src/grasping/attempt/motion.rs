//! The work cell ([`Cell`]: the world, the robot in it, its IK) and how it moves: timed joint
//! moves and straight tool moves, guarded or not, holds, and the way back to the ready pose
//! ([`park`]). Every step is timed into the attempt's [`WallTimes`].

use nalgebra::{Isometry3, Translation3, Vector3};

use crate::physics::object::ObjectHandle;
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
    /// What the arm touched that it should not (the scenery; a link another link) in the moves
    /// made whatever they touch — the way back to the ready pose when no clear way was found —
    /// since this was last emptied, each contact once; an attempt takes them into its record.
    /// Every other move is checked before it is made and not made when it would touch.
    pub arm_contacts: Vec<ArmContact>,
}

/// Steps of a planned move between two checks of the arm against the scenery and itself
/// ([`contacts_along`]; 4: every 17 ms at 240 Hz, about 2 mm of tool travel at the carry's
/// speed).
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

/// What following a trajectory found: whether a guarded move stopped on a contact, and whether
/// an arm link pushed an object.
pub(super) struct Motion {
    pub(super) stopped_by_contact: bool,
    pub(super) arm_collision: bool,
}

/// Steps a trajectory, guarded or not, recording arm-object contacts. The arm is not checked
/// against the scenery here: every move is checked before it is made ([`route`],
/// [`contacts_along`]).
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

/// What a move's check covers ([`contacts_along`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Check {
    /// The arm's links, against the scenery and each other ([`Robot::arm_contacts_at`]): the
    /// moves straight up and down, which bring the fingers near the table or a basket floor by
    /// design.
    Links,
    /// The links, and the gripper with the object it holds (if any) against the scenery
    /// ([`Robot::carried_contacts_at`]): the moves between two poses in the air.
    Carried(Option<ObjectHandle>),
}

/// What the arm would touch along `trajectory` ([`Check`]), at the joints [`follow`] would step
/// through, every [`ARM_CHECK_STEPS`] steps and the last, each contact once; only the first one
/// found when `first_only` (enough to turn a move down). The scenery is fixed, so this is what
/// following the move would meet.
pub(super) fn contacts_along(
    cell: &Cell,
    trajectory: &JointTrajectory,
    check: Check,
    first_only: bool,
) -> Vec<ArmContact> {
    let dt = f64::from(cell.world.dt_s());
    let duration = trajectory.duration_s();
    let steps = (duration / dt).ceil().max(0.0) as u32;
    let mut out = Vec::new();
    for k in (1..=steps).filter(|k| k % ARM_CHECK_STEPS == 0 || *k == steps) {
        let q = trajectory.sample((f64::from(k) * dt).min(duration));
        let mut found = cell.robot.arm_contacts_at(&cell.world, &q);
        if let Check::Carried(held) = check {
            found.extend(cell.robot.carried_contacts_at(&cell.world, &q, held));
        }
        for contact in found {
            if !out.contains(&contact) {
                out.push(contact);
                if first_only {
                    return out;
                }
            }
        }
    }
    out
}

/// The first contact along `trajectory` ([`contacts_along`]), timed as planning.
pub(super) fn first_contact(
    cell: &Cell,
    trajectory: &JointTrajectory,
    check: Check,
    wall: &mut WallTimes,
) -> Option<ArmContact> {
    wall.time(Work::Planning, || {
        contacts_along(cell, trajectory, check, true)
            .into_iter()
            .next()
    })
}

/// Follows `trajectory` whatever its links touch, recording each contact in
/// [`Cell::arm_contacts`] — for the moves that cannot be turned down (the way back to the
/// ready pose when no detour is clear).
pub(super) fn follow_recording(
    cell: &mut Cell,
    trajectory: &JointTrajectory,
    check: Check,
    wall: &mut WallTimes,
) -> Result<Motion, AttemptError> {
    let contacts = wall.time(Work::Planning, || {
        contacts_along(cell, trajectory, check, false)
    });
    for contact in contacts {
        if !cell.arm_contacts.contains(&contact) {
            cell.arm_contacts.push(contact);
        }
    }
    follow(cell, trajectory, false, wall)
}

/// How far apart the via heights of a lifted detour are ([`route`]; m).
pub const DETOUR_STEP_M: f64 = 0.05;
/// Via heights a detour tries above the higher end of the move ([`route`]).
const DETOUR_HEIGHTS: usize = 6;

/// A move the arm's links make without touching the scenery or each other: one trajectory, or
/// the legs of a detour, in order.
#[derive(Debug)]
pub(super) struct Route {
    pub(super) legs: Vec<JointTrajectory>,
    /// What the direct move would have touched first, when it was replaced by a detour.
    pub(super) avoided: Option<ArmContact>,
}

/// `direct` when the arm's links touch nothing along it; else a **lifted detour** to the tool
/// pose `direct` ends at: straight up to a via height, across at it (a joint move at the arm's
/// speeds times `speed_scale`, as the carry is, or when that is not clear a straight line), then
/// straight down — the lowest via height, from the higher of the two ends up in
/// [`DETOUR_STEP_M`] steps ([`DETOUR_HEIGHTS`] of them), whose legs are all clear. The straight
/// legs move as `params` says. `Err` with the direct move's first contact when none is: the
/// move is turned down.
pub(super) fn route(
    cell: &mut Cell,
    direct: JointTrajectory,
    check: Check,
    params: &LinearMove,
    speed_scale: f64,
    wall: &mut WallTimes,
) -> Result<Route, ArmContact> {
    let Some(contact) = first_contact(cell, &direct, check, wall) else {
        return Ok(Route {
            legs: vec![direct],
            avoided: None,
        });
    };
    let model = cell.ik.model().clone();
    let (Ok(from), Ok(to)) = (
        model.world_from_tool(&direct.start()),
        model.world_from_tool(&direct.end()),
    ) else {
        return Err(contact);
    };
    let mut arm = cell.robot.arm().clone();
    arm.max_speed_rad_s = arm.max_speed_rad_s.map(|v| v * speed_scale);
    arm.max_accel_rad_s2 = arm.max_accel_rad_s2.map(|a| a * speed_scale * speed_scale);
    let high = from.translation.vector.z.max(to.translation.vector.z);
    let same = |q: &Joints, goal: &Isometry3<f64>| {
        model.world_from_tool(q).is_ok_and(|p| {
            (p.translation.vector - goal.translation.vector).norm() < 1e-4
                && p.rotation.angle_to(&goal.rotation) < 1e-4
        })
    };
    for h in 0..DETOUR_HEIGHTS {
        let z = high + DETOUR_STEP_M * h as f64;
        let mut up = from;
        up.translation.vector.z = z;
        let mut over = to;
        over.translation.vector.z = z;
        let mut q = direct.start();
        let mut legs = Vec::new();
        let mut clear = true;
        for (goal, across) in [(up, false), (over, true), (to, false)] {
            if same(&q, &goal) {
                continue;
            }
            let q0 = q;
            let leg = wall.time(Work::Planning, || {
                let joint_move = across
                    .then(|| {
                        let q1 = cell.ik.solve(&IkTarget::Pose(goal), &q0).ok()?.joints_rad;
                        JointTrajectory::point_to_point(&arm, &q0, &q1).ok()
                    })
                    .flatten();
                joint_move.or_else(|| plan_linear_move(&mut cell.ik, &q0, &goal, params).ok())
            });
            let leg = match leg {
                Some(t) if first_contact(cell, &t, check, wall).is_none() => Some(t),
                Some(_) if across => wall
                    .time(Work::Planning, || {
                        plan_linear_move(&mut cell.ik, &q0, &goal, params).ok()
                    })
                    .filter(|t| first_contact(cell, t, check, wall).is_none()),
                _ => None,
            };
            match leg {
                Some(leg) => {
                    q = leg.end();
                    legs.push(leg);
                }
                None => {
                    clear = false;
                    break;
                }
            }
        }
        if clear {
            return Ok(Route {
                legs,
                avoided: Some(contact),
            });
        }
    }
    Err(contact)
}

/// Follows every leg of `route` (none of them guarded).
pub(super) fn follow_route(
    cell: &mut Cell,
    route: &Route,
    wall: &mut WallTimes,
) -> Result<Motion, AttemptError> {
    let mut arm_collision = false;
    for leg in &route.legs {
        arm_collision |= follow(cell, leg, false, wall)?.arm_collision;
    }
    Ok(Motion {
        stopped_by_contact: false,
        arm_collision,
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

/// A joint move to a top-down tool pose with the jaws at world yaw `yaw_rad` — exactly that yaw,
/// so that an object held is not spun about the vertical on the way (the jaws are symmetric, and
/// the IK would otherwise take `yaw_rad + π` whenever that turns the wrist less: carrying from
/// the drop region to the basket, the base's turn of about 1.6 rad then came with a half-turn of
/// the object at up to 4 rad/s, which threw thin tools out of the grip); `yaw_rad + π` only when
/// the arm cannot keep the yaw. `None` when IK or the trajectory fails.
pub(super) fn plan_joint_move(
    cell: &mut Cell,
    position_m: [f64; 3],
    yaw_rad: f64,
    speed_scale: f64,
    wall: &mut WallTimes,
) -> Option<JointTrajectory> {
    let q0 = cell.robot.joints_rad();
    wall.time(Work::Planning, || {
        let kept = TopDownGrasp {
            jaw_symmetric: false,
            ..TopDownGrasp::new(position_m, yaw_rad)
        };
        let q = match cell.ik.solve(&IkTarget::TopDown(kept), &q0) {
            Ok(s) => s.joints_rad,
            Err(_) => {
                let either = TopDownGrasp::new(position_m, yaw_rad);
                cell.ik
                    .solve(&IkTarget::TopDown(either), &q0)
                    .ok()?
                    .joints_rad
            }
        };
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
pub(super) fn jaw_yaw_rad(world_from_tool: &Isometry3<f64>) -> f64 {
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
/// baskets it does) and the links clear everything along it or a detour ([`route`]), else in a
/// straight line — where frames are taken from and the next approach starts. Moves whose links
/// touch something and have no clear detour are made anyway, their contacts recorded in
/// [`Cell::arm_contacts`].
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
        follow_recording(cell, &up, Check::Links, wall)?;
    }
    settle_opening(cell, 1.0, wall)?;
    // Straight to the ready joints when that joint move keeps the tool no lower than where it
    // is and where it goes, as the line would: from the reference basket it replaces the
    // line's joint-limited 4.3 s and the wrist's 1.7-second turn back with one 1.5–2 s move.
    // The way back cannot be turned down: when neither it, a detour nor the straight line is
    // clear, the arm goes anyway and its contacts are recorded.
    if let Some(go) = joint_move_not_below_ends(cell, &{ cell.ready_rad }, wall)
        && let Ok(way) = route(cell, go, Check::Carried(None), &config.transit, 1.0, wall)
    {
        follow_route(cell, &way, wall)?;
        return Ok(());
    }
    let yaw = jaw_yaw_rad(&cell.robot.world_from_tool());
    let ready = config.ready_position_m;
    let at = cell.robot.world_from_tool().translation.vector;
    if (at - Vector3::from(ready)).norm() > 1e-3
        && let Ok(back) = plan_straight_top_down(cell, ready, yaw, &config.transit, wall)
    {
        let check = Check::Carried(None);
        match route(cell, back.clone(), check, &config.transit, 1.0, wall) {
            Ok(way) => follow_route(cell, &way, wall)?,
            Err(_) => follow_recording(cell, &back, check, wall)?,
        };
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
            follow_recording(cell, &go, Check::Links, wall)?;
        }
    }
    Ok(())
}
