//! The robot in the physics world: the UR-class arm as six kinematic link bodies posed by forward
//! kinematics of the commanded joints, with the [`Gripper`]'s palm at the tool frame.
//!
//! **Mounting.** With the base on the floor the reference heights (table top 0.785 m, approach
//! at 1.25 m) are out of a UR5e's reach, so by default the arm stands on a fixed pedestal whose
//! top is level with the table top, beside the table: the base frame is at
//! [`DEFAULT_BASE_POSITION_M`] = (0, −0.15, 0.785), turned by −π/2 so the arm's forward (+x of
//! its base) faces the table (−y in the world). From there the reference drop region (0.05,
//! −0.52) ± 0.20 m from just above the table up to the approach height 1.25 m, and both baskets
//! at (±0.7, 0, 0.685) ± 0.1 m up to 0.35 m above their floor, take top-down grasps within the
//! joint limits (a unit test checks this with the IK). The reference's 1.25 m carry height
//! above the baskets (0.72 m out, 0.47 m up from this base) is beyond a UR5e with a 0.15 m
//! tool: carry over the baskets at ≤ 1.03 m.
//!
//! **Collisions.** The links are capsules (spheres where a DH segment is empty) that collide
//! with objects only — not with the table, the baskets, the pedestal or the gripper — so an arm
//! sweeping through an object shoves it (and [`Robot::arm_touches`] reports it), while the arm
//! never jams on the scenery it is mounted beside. The palm and fingers do collide with the
//! scenery. [`Robot::arm_contacts_at`] says what the links would touch at given joints — the
//! scenery (but the pedestal under the base link) or a link two or more joints away — and
//! [`Robot::carried_contacts_at`] what the gripper and the object held would touch in the
//! scenery; an attempt checks every move with them before it is made, and re-plans or turns
//! down one that would touch (`grasping::attempt`).
//!
//! **Driving.** [`Robot::set_joints`] commands joints for the next step; [`Robot::step_to`]
//! samples a [`JointTrajectory`] at a time and steps once; [`Robot::follow`] runs a whole
//! trajectory in sim time, optionally stopping at the first contact of the gripper (a guarded
//! move: a descent must not drive the kinematic palm through an object into the table).
//!
//! ```
//! use lgdm_sim::robot::{Robot, RobotConfig, FollowOptions};
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! use lgdm_sim::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};
//! use lgdm_sim::robot::trajectory::JointTrajectory;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let config = RobotConfig::default();
//! let home = config.arm.home_rad;
//! let mut robot = Robot::new(&mut world, config, &home, 0.085).unwrap();
//! let mut ik = IkSolver::new(robot.arm().clone(), IkConfig::default()).unwrap();
//! let above = TopDownGrasp::new([0.05, -0.52, 1.0], 0.0);
//! let q = ik.solve(&IkTarget::TopDown(above), &home).unwrap().joints_rad;
//! let go = JointTrajectory::point_to_point(robot.arm(), &home, &q).unwrap();
//! let report = robot.follow(&mut world, &go, &FollowOptions::default()).unwrap();
//! assert!(report.completed());
//! ```

pub mod arm;
pub mod gripper;
pub mod ik;
pub mod trajectory;

use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::{
    GROUP_ARM, GROUP_OBJECT, RPose, RVec, isometry_to_rapier, rapier_to_isometry,
};
use crate::physics::world::{Scenery, World};
use crate::robot::arm::{ArmModel, ArmModelError, DOF, Joints, JointsError, RigidTransform};
use crate::robot::gripper::{Gripper, GripperConfig, Touch};
use crate::robot::trajectory::JointTrajectory;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rapier3d::parry::bounding_volume::BoundingVolume;
use rapier3d::parry::query::intersection_test;
use rapier3d::parry::shape::Shape;
use rapier3d::prelude::{
    ColliderBuilder, ColliderHandle, InteractionGroups, InteractionTestMode, RigidBodyBuilder,
    RigidBodyHandle,
};
use serde::{Deserialize, Serialize};

/// Default position of the arm's base frame (m): level with the table top, 0.175 m behind the
/// table's near edge (y = −0.325), centred between the baskets.
pub const DEFAULT_BASE_POSITION_M: [f64; 3] = [0.0, -0.15, 0.785];

/// Default yaw of the arm's base frame (rad): −π/2, so the arm's forward (+x) faces −y, the
/// table.
pub const DEFAULT_BASE_YAW_RAD: f64 = -std::f64::consts::FRAC_PI_2;

/// The arm, its link geometry and the gripper. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotConfig {
    /// The arm (default: UR5e at [`DEFAULT_BASE_POSITION_M`], yaw [`DEFAULT_BASE_YAW_RAD`]).
    /// Its `flange_from_tool` is replaced by the gripper's `tool_length_m` along the flange z.
    pub arm: ArmModel,
    /// The gripper.
    pub gripper: GripperConfig,
    /// Capsule radius of each link (m; default [0.06, 0.055, 0.045, 0.04, 0.04, 0.04]).
    pub link_radius_m: [f32; DOF],
    /// A fixed pedestal box from the floor up to the base (default true).
    pub pedestal: bool,
    /// Half width of the pedestal (m; default 0.08).
    pub pedestal_half_width_m: f32,
}

impl Default for RobotConfig {
    fn default() -> Self {
        let base = Isometry3::from_parts(
            Translation3::from(Vector3::from(DEFAULT_BASE_POSITION_M)),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), DEFAULT_BASE_YAW_RAD),
        );
        Self {
            arm: ArmModel::ur5e().with_world_from_base(&base),
            gripper: GripperConfig::default(),
            link_radius_m: [0.06, 0.055, 0.045, 0.04, 0.04, 0.04],
            pedestal: true,
            pedestal_half_width_m: 0.08,
        }
    }
}

impl RobotConfig {
    /// The arm model the robot uses: `arm` with the gripper's tool length.
    pub fn effective_arm(&self) -> ArmModel {
        let mut arm = self.arm.clone();
        arm.flange_from_tool =
            RigidTransform::from_translation_m(0.0, 0.0, f64::from(self.gripper.tool_length_m));
        arm
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RobotError> {
        self.effective_arm().validate()?;
        self.gripper.validate()?;
        for (i, r) in self.link_radius_m.iter().enumerate() {
            if !(r.is_finite() && *r > 0.0) {
                return Err(WorldError::InvalidConfig {
                    field: format!("link_radius_m[{i}]"),
                    reason: format!("{r} must be positive and finite"),
                }
                .into());
            }
        }
        if !(self.pedestal_half_width_m.is_finite() && self.pedestal_half_width_m > 0.0) {
            return Err(WorldError::InvalidConfig {
                field: "pedestal_half_width_m".into(),
                reason: format!("{} must be positive and finite", self.pedestal_half_width_m),
            }
            .into());
        }
        Ok(())
    }
}

/// Errors of the robot.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RobotError {
    /// A world-level error (config, pose).
    #[error(transparent)]
    World(#[from] WorldError),
    /// A bad arm model.
    #[error(transparent)]
    Arm(#[from] ArmModelError),
    /// Commanded joints are NaN or outside the limits.
    #[error("commanded joints: {0}")]
    Joints(#[from] JointsError),
}

/// Options of [`Robot::follow`].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FollowOptions {
    /// Stop (hold the current joints) after the first step in which the palm or a finger
    /// pushes on anything (default false).
    pub stop_on_contact: bool,
}

/// What [`Robot::follow`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowReport {
    /// Steps taken.
    pub steps: u32,
    /// Trajectory time reached (s).
    pub t_s: f64,
    /// The trajectory's duration (s).
    pub duration_s: f64,
    /// The contacts that stopped a guarded move (empty if it ran to the end).
    pub stopped_by: Vec<Touch>,
}

impl FollowReport {
    /// Whether the whole trajectory ran.
    pub fn completed(&self) -> bool {
        self.stopped_by.is_empty()
    }
}

/// The robot: kinematic arm links and the gripper, as handles into a [`World`].
#[derive(Debug, Clone)]
pub struct Robot {
    arm: ArmModel,
    links: [RigidBodyHandle; DOF],
    link_colliders: [ColliderHandle; DOF],
    gripper: Gripper,
    q_rad: Joints,
}

/// Links at least this many joints apart are checked against each other
/// ([`Robot::arm_contacts_at`]); nearer ones share a joint and overlap there by construction.
pub const SELF_GAP: usize = 2;

/// A part of the arm touching what it should not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ArmContact {
    /// The part.
    pub part: ArmPart,
    /// What it touches.
    pub with: ArmContactee,
}

/// The part of the arm an [`ArmContact`] is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmPart {
    /// A link, 1 (shoulder) to 6 (the last wrist link).
    Link(usize),
    /// The gripper: its palm or a finger.
    Gripper,
    /// The object the gripper holds.
    Held,
}

/// What an arm part touches ([`ArmContact`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmContactee {
    /// A piece of the fixed scenery.
    Scenery(Scenery),
    /// A link of the arm (1 to 6).
    Link(usize),
}

impl std::fmt::Display for ArmPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ArmPart::Link(i) => write!(f, "link {i}"),
            ArmPart::Gripper => f.write_str("the gripper"),
            ArmPart::Held => f.write_str("the object held"),
        }
    }
}

impl std::fmt::Display for ArmContact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.with {
            ArmContactee::Scenery(what) => write!(f, "{} touches {what}", self.part),
            ArmContactee::Link(j) => write!(f, "{} touches link {j}", self.part),
        }
    }
}

/// Whether two shapes at their poses intersect: their bounding boxes first (most pairs of a
/// link or a held object and the scenery are far apart), then parry's exact test.
fn touch(p1: &RPose, s1: &dyn Shape, p2: &RPose, s2: &dyn Shape) -> bool {
    s1.compute_aabb(p1).intersects(&s2.compute_aabb(p2))
        && intersection_test(p1, s1, p2, s2).is_ok_and(|hit| hit.intersecting)
}

fn arm_groups() -> InteractionGroups {
    InteractionGroups::new(GROUP_ARM, GROUP_OBJECT, InteractionTestMode::And)
}

impl Robot {
    /// Builds the links at joints `q_rad`, the pedestal (if configured) and the gripper with the
    /// given opening.
    pub fn new(
        world: &mut World,
        config: RobotConfig,
        q_rad: &Joints,
        opening_m: f32,
    ) -> Result<Self, RobotError> {
        config.validate()?;
        let arm = config.effective_arm();
        arm.check_joints(q_rad)?;
        let pose = arm.forward(q_rad)?;
        if config.pedestal {
            let base = pose.world_from_base.translation.vector;
            let top = base.z as f32;
            if top > 0.0 {
                let w = config.pedestal_half_width_m;
                world.add_fixed_box(
                    Scenery::Pedestal,
                    [base.x as f32, base.y as f32, 0.5 * top],
                    [w, w, 0.5 * top],
                    0.5,
                );
            }
        }
        let mut links = Vec::with_capacity(DOF);
        let mut link_colliders = Vec::with_capacity(DOF);
        for i in 0..DOF {
            let dh = &arm.dh[i];
            // The previous frame's origin in link i's frame: Rx(−α)·(−a, 0, −d), constant.
            let prev = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -dh.alpha_rad)
                * Vector3::new(-dh.a_m, 0.0, -dh.d_m);
            let radius = config.link_radius_m[i];
            let collider = if prev.norm() < 1e-6 {
                ColliderBuilder::ball(radius)
            } else {
                ColliderBuilder::capsule_from_endpoints(
                    RVec::new(prev.x as f32, prev.y as f32, prev.z as f32),
                    RVec::ZERO,
                    radius,
                )
            }
            .collision_groups(arm_groups());
            let link_pose =
                isometry_to_rapier(&pose.world_from_link[i]).ok_or(WorldError::NonFinitePose {
                    what: format!("arm link {}", i + 1),
                })?;
            let (body, collider) = world.physics.insert(
                RigidBodyBuilder::kinematic_position_based().pose(link_pose),
                collider,
            );
            links.push(body);
            link_colliders.push(collider);
        }
        let gripper = Gripper::new(world, config.gripper, &pose.world_from_tool, opening_m)?;
        Ok(Self {
            arm,
            links: links.try_into().expect("DOF links"),
            link_colliders: link_colliders.try_into().expect("DOF colliders"),
            gripper,
            q_rad: *q_rad,
        })
    }

    /// The arm model in use (with the gripper's tool length): build the IK solver from this.
    pub fn arm(&self) -> &ArmModel {
        &self.arm
    }

    /// The gripper.
    pub fn gripper(&self) -> &Gripper {
        &self.gripper
    }

    /// The gripper, for opening commands.
    pub fn gripper_mut(&mut self) -> &mut Gripper {
        &mut self.gripper
    }

    /// The link bodies 1..6 (for the recorder).
    pub(crate) fn link_bodies(&self) -> [RigidBodyHandle; DOF] {
        self.links
    }

    /// The commanded joints (rad).
    pub fn joints_rad(&self) -> Joints {
        self.q_rad
    }

    /// The commanded tool (palm) pose.
    pub fn world_from_tool(&self) -> Isometry3<f64> {
        self.arm.forward_unchecked(&self.q_rad).world_from_tool
    }

    /// Poses of links 1..6 at the commanded joints (for drawing and recording).
    pub fn world_from_links(&self) -> [Isometry3<f64>; DOF] {
        self.arm.forward_unchecked(&self.q_rad).world_from_link
    }

    /// Commands joints for the next step (finite and inside the limits). The kinematic links
    /// move there in one step, so successive commands must be close (follow a trajectory).
    pub fn set_joints(&mut self, q_rad: &Joints) -> Result<(), RobotError> {
        self.arm.check_joints(q_rad)?;
        self.q_rad = *q_rad;
        Ok(())
    }

    fn apply(&mut self, world: &mut World) -> Result<(), RobotError> {
        let pose = self.arm.forward_unchecked(&self.q_rad);
        for (i, body) in self.links.iter().enumerate() {
            let target =
                isometry_to_rapier(&pose.world_from_link[i]).ok_or(WorldError::NonFinitePose {
                    what: format!("arm link {}", i + 1),
                })?;
            if let Some(b) = world.physics.bodies.get_mut(*body) {
                b.set_next_kinematic_position(target);
            }
        }
        self.gripper.set_palm_pose(&pose.world_from_tool)?;
        self.gripper.apply(world);
        Ok(())
    }

    /// Moves the links and the palm to the commanded joints and steps the world once.
    pub fn step(&mut self, world: &mut World) -> Result<(), RobotError> {
        self.apply(world)?;
        world.step();
        Ok(())
    }

    /// Commands `trajectory.sample(t_s)` and steps once.
    pub fn step_to(
        &mut self,
        world: &mut World,
        trajectory: &JointTrajectory,
        t_s: f64,
    ) -> Result<(), RobotError> {
        self.set_joints(&trajectory.sample(t_s))?;
        self.step(world)
    }

    /// Runs `trajectory` from its start in sim time, one sample per step, until its end (the
    /// last step lands exactly on the end) or, with `stop_on_contact`, until the gripper first
    /// pushes on something; the joints then hold where they are.
    pub fn follow(
        &mut self,
        world: &mut World,
        trajectory: &JointTrajectory,
        options: &FollowOptions,
    ) -> Result<FollowReport, RobotError> {
        let dt = f64::from(world.dt_s());
        let duration_s = trajectory.duration_s();
        let steps = (duration_s / dt).ceil().max(0.0) as u32;
        for k in 1..=steps {
            let t_s = (f64::from(k) * dt).min(duration_s);
            self.step_to(world, trajectory, t_s)?;
            if options.stop_on_contact {
                let touches = self.gripper.touches(world);
                if !touches.is_empty() {
                    return Ok(FollowReport {
                        steps: k,
                        t_s,
                        duration_s,
                        stopped_by: touches,
                    });
                }
            }
        }
        Ok(FollowReport {
            steps,
            t_s: duration_s,
            duration_s,
            stopped_by: Vec::new(),
        })
    }

    /// Holds the commanded joints for `steps` steps (e.g. while the gripper closes).
    pub fn hold(&mut self, world: &mut World, steps: u32) -> Result<(), RobotError> {
        for _ in 0..steps {
            self.step(world)?;
        }
        Ok(())
    }

    /// Objects the arm's links push on over the last step (collision on approach), sorted.
    pub fn arm_touches(&self, world: &World) -> Vec<ObjectHandle> {
        let mut out = Vec::new();
        for collider in &self.link_colliders {
            for pair in world.physics.narrow_phase.contact_pairs_with(*collider) {
                if !(pair.has_any_active_contact() && pair.total_impulse_magnitude() > 0.0) {
                    continue;
                }
                let other = if pair.collider1 == *collider {
                    pair.collider2
                } else {
                    pair.collider1
                };
                if let Some(object) = world.object_of_collider(other) {
                    out.push(object);
                }
            }
        }
        out.sort();
        out.dedup();
        out
    }

    /// What the arm's links would touch at joints `q_rad` (the robot does not move): a piece
    /// of the scenery — the table, a basket, the floor, the pedestal under any link but the
    /// base's — or a link two or more joints away ([`ArmContact`]); empty when `q_rad` is
    /// clear, or outside the joint limits (the IK never plans there).
    pub fn arm_contacts_at(&self, world: &World, q_rad: &Joints) -> Vec<ArmContact> {
        let Ok(pose) = self.arm.forward(q_rad) else {
            return Vec::new();
        };
        let links: Vec<_> = (0..DOF)
            .filter_map(|i| {
                let p = isometry_to_rapier(&pose.world_from_link[i])?;
                let shape = world.physics.colliders.get(self.link_colliders[i])?.shape();
                Some((i, p, shape))
            })
            .collect();
        let mut out = Vec::new();
        for &(i, ref p, shape) in &links {
            for &(c, what) in world.scenery() {
                if i == 0 && what == Scenery::Pedestal {
                    continue;
                }
                let Some(collider) = world.physics.colliders.get(c) else {
                    continue;
                };
                if touch(p, shape, collider.position(), collider.shape()) {
                    out.push(ArmContact {
                        part: ArmPart::Link(i + 1),
                        with: ArmContactee::Scenery(what),
                    });
                }
            }
        }
        for &(i, ref pi, si) in &links {
            for &(j, ref pj, sj) in links.iter().filter(|(j, _, _)| *j >= i + SELF_GAP) {
                if touch(pi, si, pj, sj) {
                    out.push(ArmContact {
                        part: ArmPart::Link(i + 1),
                        with: ArmContactee::Link(j + 1),
                    });
                }
            }
        }
        out
    }

    /// What the gripper (its palm and fingers) and the object `held`, carried rigidly at the
    /// tool as they are now, would touch in the scenery with the arm at joints `q_rad`
    /// ([`ArmPart::Gripper`], [`ArmPart::Held`]); empty outside the joint limits. For moves
    /// between two poses in the air (the approach, the carry, the way back), where the fingers
    /// and what they hold should meet nothing fixed: the descent and the lowering into a basket
    /// bring them close to the table and the floor by design.
    pub fn carried_contacts_at(
        &self,
        world: &World,
        q_rad: &Joints,
        held: Option<ObjectHandle>,
    ) -> Vec<ArmContact> {
        let Ok(pose) = self.arm.forward(q_rad) else {
            return Vec::new();
        };
        let tool_now = self.world_from_tool();
        let mut carried: Vec<(ArmPart, ColliderHandle)> = self
            .gripper
            .part_colliders()
            .into_iter()
            .map(|(_, c)| (ArmPart::Gripper, c))
            .collect();
        if let Some(c) = held.and_then(|h| world.object_collider(h).ok()) {
            carried.push((ArmPart::Held, c));
        }
        let mut out = Vec::new();
        for (part, c) in carried {
            let Some(collider) = world.physics.colliders.get(c) else {
                continue;
            };
            let tool_from_part = tool_now.inverse() * rapier_to_isometry(collider.position());
            let Some(at) = isometry_to_rapier(&(pose.world_from_tool * tool_from_part)) else {
                continue;
            };
            for &(s, what) in world.scenery() {
                let Some(scenery) = world.physics.colliders.get(s) else {
                    continue;
                };
                let contact = ArmContact {
                    part,
                    with: ArmContactee::Scenery(what),
                };
                if !out.contains(&contact)
                    && touch(&at, collider.shape(), scenery.position(), scenery.shape())
                {
                    out.push(contact);
                }
            }
        }
        out
    }

    /// The link capsules' endpoints in the world at the commanded joints (m; for drawing).
    pub fn link_segments_m(&self) -> [([f64; 3], [f64; 3]); DOF] {
        let pose = self.arm.forward_unchecked(&self.q_rad);
        std::array::from_fn(|i| {
            let a = if i == 0 {
                pose.world_from_base.translation.vector
            } else {
                pose.world_from_link[i - 1].translation.vector
            };
            let b = pose.world_from_link[i] * Point3::origin();
            ([a.x, a.y, a.z], [b.x, b.y, b.z])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;
    use crate::robot::gripper::GripperModel;
    use crate::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};

    /// The default mounting reaches the reference workspace with top-down grasps, with either
    /// gripper: the drop region (0.05, −0.52) ± 0.20 m from just above the table up to the
    /// approach height 1.25 m, and above both baskets (± 0.1 m) up to the carry height and
    /// beyond — 0.35 m above their floor (z = 1.035 m) with the 2F-85's 0.15 m tool, 0.345 m
    /// (the carry height 1.03 m) with the 2F-140's 0.2 m one (the reference's 1.25 m over the
    /// baskets is 0.72 m out and 0.47 m up from the base: beyond a UR5e with either tool).
    #[test]
    fn default_mounting_reaches_reference_workspace() {
        for (model, highest) in [
            (GripperModel::Robotiq2F85, 0.35),
            (GripperModel::Robotiq2F140, 0.33),
        ] {
            reaches_reference_workspace(model, highest);
        }
    }

    fn reaches_reference_workspace(model: GripperModel, highest_above_basket_m: f64) {
        let config = RobotConfig {
            gripper: GripperConfig::preset(model),
            ..RobotConfig::default()
        };
        let arm = config.effective_arm();
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
        let top = 0.785;
        let mut targets = Vec::new();
        for dx in [-0.2, -0.1, 0.0, 0.1, 0.2] {
            for dy in [-0.2, -0.1, 0.0, 0.1, 0.2] {
                for z in [top + 0.01, top + 0.05, top + 0.15, 1.25] {
                    targets.push([0.05 + dx, -0.52 + dy, z]);
                }
            }
        }
        for x in [-0.7, 0.7] {
            for (dx, dy) in [
                (0.0, 0.0),
                (-0.1, -0.1),
                (0.1, 0.1),
                (-0.1, 0.1),
                (0.1, -0.1),
            ] {
                for z in [0.685 + 0.15, 0.685 + 0.25, 0.685 + highest_above_basket_m] {
                    targets.push([x + dx, dy, z]);
                }
            }
            targets.push([
                x,
                0.0,
                crate::grasping::attempt::AttemptConfig::default().carry_height_m,
            ]);
        }
        let mut failures = Vec::new();
        for p in &targets {
            for yaw in [0.0, 0.8, 1.6, 2.4] {
                let grasp = TopDownGrasp::new(*p, yaw);
                if let Err(e) = ik.solve(&IkTarget::TopDown(grasp), &arm.home_rad) {
                    failures.push(format!("{p:?} yaw {yaw}: {e}"));
                }
            }
        }
        assert!(
            failures.is_empty(),
            "{}: {} unreachable:\n{}",
            model.name(),
            failures.len(),
            failures.join("\n")
        );
    }

    #[test]
    fn robot_config_validation_names_the_field() {
        let mut cfg = RobotConfig::default();
        cfg.link_radius_m[3] = 0.0;
        assert!(matches!(
            cfg.validate(),
            Err(RobotError::World(WorldError::InvalidConfig { field, .. })) if field == "link_radius_m[3]"
        ));
        let mut cfg = RobotConfig::default();
        cfg.gripper.stroke_m = -1.0;
        assert!(
            cfg.validate()
                .unwrap_err()
                .to_string()
                .contains("gripper.stroke_m")
        );
        let mut world = World::new(WorldConfig::default()).unwrap();
        let cfg = RobotConfig::default();
        let mut q = cfg.arm.home_rad;
        q[2] = 10.0;
        assert!(matches!(
            Robot::new(&mut world, cfg, &q, 0.0),
            Err(RobotError::Joints(JointsError::OutsideLimits {
                joint: 2,
                ..
            }))
        ));
    }

    #[test]
    fn palm_sits_at_the_tool_frame() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let cfg = RobotConfig::default();
        let home = cfg.arm.home_rad;
        let mut robot = Robot::new(&mut world, cfg, &home, 0.085).unwrap();
        robot.hold(&mut world, 2).unwrap();
        let palm = robot.gripper().palm_pose(&world);
        let tool = robot.world_from_tool();
        assert!((palm.translation.vector - tool.translation.vector).norm() < 1e-5);
        assert!(palm.rotation.angle_to(&tool.rotation) < 1e-5);
        // Top-down at home: the pads point down.
        assert!((tool.rotation * Vector3::z()).z < -0.999);
    }

    /// A robot at home in a world with `config`.
    fn at_home(config: WorldConfig) -> (World, Robot) {
        let mut world = World::new(config).unwrap();
        let robot_config = RobotConfig::default();
        let home = robot_config.arm.home_rad;
        let robot = Robot::new(&mut world, robot_config, &home, 0.085).unwrap();
        (world, robot)
    }

    #[test]
    fn the_arm_at_home_touches_nothing_it_should_not() {
        let (world, robot) = at_home(WorldConfig::default());
        assert_eq!(robot.arm_contacts_at(&world, &robot.joints_rad()), []);
    }

    /// A table raised around the elbow is found touching the links there; the pedestal under
    /// the base link is not reported.
    #[test]
    fn a_link_inside_the_table_is_a_contact() {
        let (_, probe) = at_home(WorldConfig::default());
        let pose = probe.arm().forward(&probe.joints_rad()).unwrap();
        let elbow = pose.world_from_link[2].translation.vector;
        let mut config = WorldConfig::default();
        config.table.center_m = [elbow.x as f32, elbow.y as f32, elbow.z as f32];
        config.table.size_m = [0.1, 0.1, 0.1];
        let (world, robot) = at_home(config);
        let contacts = robot.arm_contacts_at(&world, &robot.joints_rad());
        assert!(
            contacts.contains(&ArmContact {
                part: ArmPart::Link(3),
                with: ArmContactee::Scenery(Scenery::Table),
            }),
            "{contacts:?}"
        );
        assert!(
            contacts
                .iter()
                .all(|c| c.with != ArmContactee::Scenery(Scenery::Pedestal)),
            "{contacts:?}"
        );
        let table = ArmContact {
            part: ArmPart::Link(3),
            with: ArmContactee::Scenery(Scenery::Table),
        };
        assert_eq!(table.to_string(), "link 3 touches the table");
    }

    /// The elbow folded shut brings the wrist onto the upper arm.
    #[test]
    fn a_folded_arm_touches_itself() {
        let (world, robot) = at_home(WorldConfig::default());
        let mut q = robot.joints_rad();
        q[2] = 3.0;
        let contacts = robot.arm_contacts_at(&world, &q);
        assert!(
            contacts
                .iter()
                .any(|c| matches!((c.part, c.with), (ArmPart::Link(i), ArmContactee::Link(j)) if j >= i + SELF_GAP)),
            "{contacts:?}"
        );
    }

    /// A table raised to the tool at home holds the gripper: a contact of the gripper, and none
    /// of the links.
    #[test]
    fn a_gripper_inside_the_table_is_a_contact() {
        let (_, probe) = at_home(WorldConfig::default());
        let tool = probe.world_from_tool().translation.vector;
        let mut config = WorldConfig::default();
        config.table.center_m = [tool.x as f32, tool.y as f32, tool.z as f32];
        config.table.size_m = [0.1, 0.1, 0.02];
        let (world, robot) = at_home(config);
        let q = robot.joints_rad();
        let gripper = ArmContact {
            part: ArmPart::Gripper,
            with: ArmContactee::Scenery(Scenery::Table),
        };
        assert_eq!(robot.carried_contacts_at(&world, &q, None), [gripper]);
        assert_eq!(gripper.to_string(), "the gripper touches the table");
        assert_eq!(robot.arm_contacts_at(&world, &q), []);
    }
}
