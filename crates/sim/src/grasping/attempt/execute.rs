//! One attempt in phases ([`execute`]: approach, descend, close, lift, judge the grasp, carry,
//! release, judge the placement), each adding to what it measured ([`Execution`],
//! [`Measurements`]).

use lgdm_pointcloud::math::transform_point;
use serde::{Deserialize, Serialize};

use crate::physics::config::BasketConfig;
use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::robot::trajectory::{JointTrajectory, LinearMove};
use crate::robot::{ArmContact, RobotError};
use crate::timing::{WallTimes, Work};

use super::config::{AttemptConfig, AttemptError};
use super::motion::{
    Cell, Check, Route, first_contact, follow, follow_route, hold, jaw_yaw_rad, plan_joint_move,
    plan_straight, plan_straight_top_down, route, settle_opening,
};
use super::plan::GraspPlan;
use super::verdict::{
    FailureReason, grasp_verdict, pinched_objects, touching_objects, width_between_pads_m,
};

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
    /// What the arm's links touched that they should not — the table, a basket, the floor,
    /// the pedestal, each other — from the ready pose through the way back to it, each
    /// contact once. Every move of the attempt is checked before it is made and avoided
    /// (`avoided_contacts`), so these come from the way back, which is made even when neither
    /// it nor a detour is clear ([`crate::grasping::attempt::park`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub arm_contacts: Vec<ArmContact>,
    /// What the arm's links would have touched in the moves the attempt planned, had they been
    /// made as planned: each was replaced by a lifted detour (`detours`), left out (the lowering
    /// into the basket, the rise after the release: the object is released higher, the arm
    /// parks from where it is) or turned down (the attempt fails as `arm_collision`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub avoided_contacts: Vec<ArmContact>,
    /// Moves replaced by a lifted detour because their links would have touched something.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub detours: u32,
    /// When it was inside the basket but faster than at rest: how far its centre of mass moved
    /// (m) and how far it turned (rad) over the next [`REST_WINDOW_S`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placed_drift: Option<[f32; 2]>,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// How long an object inside the basket but not slower than at rest is watched (s; 0.5).
pub const REST_WINDOW_S: f64 = 0.5;
/// It is at rest when its centre of mass moved less than this over the window (m; 0.003)…
pub const REST_DRIFT_M: f32 = 0.003;
/// …and it turned less than this (rad; 0.1, about 6°). The solver's tremble turns a lying
/// stick or slab by up to 0.066 rad between two looks 0.5 s apart (the irregular validation
/// set, `lgdm sim objects --set irregular --seed 0`), with its centre moving 1 mm at most.
pub const REST_TURN_RAD: f32 = 0.1;

/// How far inside the basket's wall the highest carry point may be, at the most, on the side
/// toward the arm (m): room for a held object's half width.
pub const CARRY_INSET_M: f64 = 0.06;

/// Points tried between the basket's centre and [`CARRY_INSET_M`] from its near wall.
const CARRY_VIA_STEPS: usize = 5;

/// Runs one grasp attempt from the current state of `cell` (the arm parked, the gripper open):
/// approach, descend, close, lift, judge, carry, release, judge (one private function per
/// phase). `target` is the object the grasp aimed at (for judging when nothing was pinched);
/// every live object's resting centre-of-mass height is read at the start, for the rise. The
/// arm is left where the attempt ended; see [`crate::grasping::attempt::park`].
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
    cell.arm_contacts.clear();
    let mut attempt = Attempt {
        cell,
        plan,
        config,
        wall,
        out: Execution::default(),
    };
    let outcome = attempt.run(target, &rest);
    attempt.out.measured.arm_contacts = std::mem::take(&mut attempt.cell.arm_contacts);
    match outcome {
        Ok(()) => Ok(attempt.out),
        Err(Stop::Failed(reason)) => {
            attempt.out.reason = Some(reason);
            Ok(attempt.out)
        }
        Err(Stop::Error(e)) => Err(e),
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
        let (basket, at) = match self.carry(object) {
            Err(Stop::Failed(FailureReason::ArmCollision)) => {
                self.put_back(descent.reached_z_m)?;
                return Err(Stop::Failed(FailureReason::ArmCollision));
            }
            other => other?,
        };
        self.release(at)?;
        self.judge_placement(object, &basket)
    }

    /// Records a contact a planned move would have made.
    fn avoided(&mut self, contact: ArmContact) {
        let avoided = &mut self.out.measured.avoided_contacts;
        if !avoided.contains(&contact) {
            avoided.push(contact);
        }
    }

    /// `direct`, or a lifted detour when its links would touch something ([`route`]); turned
    /// down as `arm_collision` when no detour is clear.
    fn clear_route(
        &mut self,
        direct: JointTrajectory,
        check: Check,
        params: &LinearMove,
        speed_scale: f64,
    ) -> Result<Route, Stop> {
        match route(self.cell, direct, check, params, speed_scale, self.wall) {
            Ok(way) => {
                if let Some(contact) = way.avoided {
                    self.avoided(contact);
                    self.out.measured.detours += 1;
                }
                Ok(way)
            }
            Err(contact) => {
                self.avoided(contact);
                Err(Stop::Failed(FailureReason::ArmCollision))
            }
        }
    }

    /// A move straight up or down, which no detour replaces: turned down as `arm_collision`
    /// when its links would touch something.
    fn clear_or_refuse(&mut self, straight: &JointTrajectory) -> Result<(), Stop> {
        match first_contact(self.cell, straight, Check::Links, self.wall) {
            Some(contact) => {
                self.avoided(contact);
                Err(Stop::Failed(FailureReason::ArmCollision))
            }
            None => Ok(()),
        }
    }

    /// Whether a move the attempt can do without (the lowering into the basket, the rise
    /// after the release) is clear; the contact it would have made is recorded when it is not.
    fn clear_or_leave_out(&mut self, optional: &JointTrajectory) -> bool {
        match first_contact(self.cell, optional, Check::Links, self.wall) {
            Some(contact) => {
                self.avoided(contact);
                false
            }
            None => true,
        }
    }

    /// Phase 1, pre-grasp: a straight move down from the ready pose, opening meanwhile — or a
    /// lifted detour when the arm's links would touch something on the way ([`route`]).
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
        let config = self.config;
        let way = self.clear_route(approach, Check::Carried(None), &config.transit, 1.0)?;
        let m = follow_route(self.cell, &way, self.wall)?;
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
        self.clear_or_refuse(&descent)?;
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
        self.clear_or_refuse(&lift)?;
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
        // The jaws' yaw as they are now (the approach may have taken the grasp's yaw + π).
        let yaw = jaw_yaw_rad(&self.cell.robot.world_from_tool());
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
        let way = self.clear_route(
            carry,
            Check::Carried(Some(object)),
            &config.lift,
            config.carry_speed_scale,
        )?;
        follow_route(self.cell, &way, self.wall)?;
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
            && self.clear_or_leave_out(&lower)
        {
            follow(self.cell, &lower, false, self.wall)?;
        }
        if !still_holds(self.cell, object)? {
            return Err(Stop::Failed(FailureReason::SlippedDuringCarry));
        }
        Ok((basket, [bx, by]))
    }

    /// When the carry was turned down: lowers the object held straight back to where it was
    /// grasped (the tool 1 cm above where the descent stopped), when that move is clear, and
    /// opens — rather than dropping it from the lift's height.
    fn put_back(&mut self, grasped_z_m: f64) -> Result<(), Stop> {
        let [x, y, _] = self.plan.tcp_m;
        let config = self.config;
        if let Ok(down) = plan_straight(
            self.cell,
            [x, y, grasped_z_m + 0.01],
            &config.lift,
            self.wall,
        ) && self.clear_or_leave_out(&down)
        {
            follow(self.cell, &down, false, self.wall)?;
        }
        let stroke = self.cell.robot.gripper().config().stroke_m;
        self.cell.robot.gripper_mut().set_opening(stroke)?;
        settle_opening(self.cell, 2.0, self.wall)?;
        Ok(())
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
        if let Ok(up) = plan_straight(self.cell, up, &config.lift, self.wall)
            && self.clear_or_leave_out(&up)
        {
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

    /// Phase 5: judge the placement: `object` at rest inside `basket`. At rest is slower than
    /// 2 cm/s and 0.2 rad/s, or, when it is not, a pose that moves less than
    /// [`REST_DRIFT_M`] and [`REST_TURN_RAD`] over the next [`REST_WINDOW_S`]: the solver can
    /// keep a thin or finely faceted object that lies still (a slab, a stick) trembling at
    /// 1 cm/s and 1 rad/s for as long as it is watched, while its pose does not change by a
    /// millimetre.
    fn judge_placement(&mut self, object: ObjectHandle, basket: &BasketConfig) -> Result<(), Stop> {
        let world = &self.cell.world;
        let com = world.object_center_of_mass_m(object)?;
        self.out.measured.placed_at_m = Some(com);
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
        let mut at_rest = speed < 0.02 && spin < 0.2;
        self.out.measured.placed_motion = Some([speed, spin]);
        self.out.measured.placed_lowest_z_m = Some(lowest);
        if inside && !at_rest {
            hold(self.cell, REST_WINDOW_S, self.wall)?;
            let world = &self.cell.world;
            let later = world.object_pose(object)?;
            let moved = world.object_center_of_mass_m(object)?;
            let drift = (0..3)
                .map(|i| (moved[i] - com[i]).powi(2))
                .sum::<f32>()
                .sqrt();
            // The angle of the relative rotation, its cosine clamped: float error can put
            // the trace of a rotation by nothing a hair above 3 (`angle()` is then NaN).
            let relative = pose.rotation.inverse() * later.rotation;
            let turn = ((relative.matrix().trace() - 1.0) / 2.0)
                .clamp(-1.0, 1.0)
                .acos();
            self.out.measured.placed_drift = Some([drift, turn]);
            at_rest = drift < REST_DRIFT_M && turn < REST_TURN_RAD;
        }
        self.out.placement_success = inside && at_rest;
        match (inside, at_rest) {
            (true, true) => Ok(()),
            (true, false) => Err(Stop::Failed(FailureReason::StillMoving)),
            (false, _) => Err(Stop::Failed(FailureReason::DroppedOutside)),
        }
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
