//! A parallel-jaw gripper in the physics world: a kinematic palm driven by pose (each step it
//! moves to the commanded `world_from_palm`) and two **dynamic** fingers on prismatic impulse
//! joints, each driven by a force-limited position motor.
//!
//! The outcome of a grasp comes from contacts and friction only: the gripper never welds,
//! attaches or teleports an object. Kinematic fingers would pinch an object between two
//! infinite masses (jitter, ejection); force-limited dynamic fingers squeeze like a
//! Robotiq-class gripper's force-limited close.
//!
//! The squeeze: while closing, the motors' common set-point ramps down at `opening_speed_m_s`
//! but never further than `grip_force_n / motor_stiffness_n_m` inside the fingers' measured
//! half gap. Once the pads stall on an object each motor therefore pushes with
//! [`GripperConfig::grip_force_n`] — below its `max_force_n` limit, so the two position springs
//! also keep the object centred between the pads (two saturated motors would let fingers and
//! object drift sideways together, ~1.5 mm/s). With nothing between the pads the set-point
//! follows the closing fingers down to 0.
//!
//! Frames: the palm body's frame is the tool frame (`world_from_palm` = the arm's
//! `world_from_tool`), with its origin at the centre between the two finger pads, z pointing
//! out of the gripper toward the object (down for a top-down grasp), and x the opening
//! direction: finger 0 sits on −x, finger 1 on +x. The pads are `finger_length_m` long along z
//! (centred on the origin) and `finger_width_m` wide along y. The palm box sits above the pads,
//! up to the flange at z = −[`GripperConfig::tool_length_m`].
//!
//! Commands: [`Gripper::set_palm_pose`] (applied as the kinematic target at the next step) and
//! [`Gripper::set_opening`] (a target the motor set-point ramps toward at
//! `opening_speed_m_s`, never jumps). Read-backs: [`Gripper::finger_gap_m`] measured from the
//! body poses (not from contact depths, which rapier recycles), [`Gripper::contacts_with`] per
//! finger with the normal force from the contact impulses, and [`Gripper::touches`] for guarded
//! moves (stop on first contact).
//!
//! ```
//! use lgdm_sim::robot::gripper::{Gripper, GripperConfig};
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! // Pads pointing down, 10 cm above the table top.
//! let world_from_palm = Isometry3::from_parts(
//!     Translation3::new(0.0, -0.6, 0.885),
//!     UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
//! );
//! let mut gripper = Gripper::new(&mut world, GripperConfig::default(), &world_from_palm, 0.085).unwrap();
//! gripper.set_opening(0.0).unwrap();
//! for _ in 0..240 {
//!     gripper.step(&mut world);
//! }
//! assert!(gripper.finger_gap_m(&world) < 1e-3); // closed on nothing
//! ```

use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::{
    GROUP_GRIPPER, GROUP_OBJECT, GROUP_STATIC, RPose, RVec, isometry_to_rapier, rapier_to_isometry,
};
use crate::physics::world::World;
use nalgebra::{Isometry3, Translation3, Vector3};
use rapier3d::prelude::{
    CoefficientCombineRule, ColliderBuilder, ColliderHandle, ImpulseJointHandle, InteractionGroups,
    InteractionTestMode, JointAxis, MotorModel, PrismaticJointBuilder, RigidBodyBuilder,
    RigidBodyHandle,
};
use serde::{Deserialize, Serialize};

/// Geometry, mass and drive of the gripper. The default is the 2F-140's preset
/// ([`GripperConfig::preset`]); each field states the 2F-85's value and, where it differs, the
/// 2F-140's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GripperConfig {
    /// Largest opening between the pads (m; 2F-140 0.14; 2F-85 0.085, the reference's
    /// `MAX_GRASP`).
    pub stroke_m: f32,
    /// Pad width along the palm's y (m; default 0.02 = the grasp labels'
    /// `DEFAULT_FINGER_WIDTH_M`).
    pub finger_width_m: f32,
    /// Pad length along the approach axis (m; 2F-140 0.065, 2F-85 0.05).
    pub finger_length_m: f32,
    /// Pad thickness along the opening axis (m; default 0.01).
    pub finger_thickness_m: f32,
    /// Finger density (kg/m³; default 8000, ~80 g a finger: lighter fingers (8 g) were unstable
    /// against 40–100 N motors in the prototype).
    pub finger_density_kg_m3: f32,
    /// Pad friction coefficient (default 1.0, the reference pads' `lateralFriction`).
    pub finger_friction: f32,
    /// Distance from the flange to the pad centre (m; 2F-140 0.2, 2F-85 0.15: the arm's default
    /// tool).
    pub tool_length_m: f32,
    /// Half width of the palm box along y (m; default 0.03).
    pub palm_half_width_m: f32,
    /// Motor stiffness (N/m; default 1e4, force-based: 4 mm of set-point error already
    /// saturates the default force).
    pub motor_stiffness_n_m: f32,
    /// Motor damping (N·s/m; default 200).
    pub motor_damping_n_s_m: f32,
    /// Squeeze force of each finger once the pads stall on an object (N; default 40: the
    /// prototype's value, enough for 0.5 kg at μ 1 with a wide margin; a slippery μ 0.05 object
    /// of 0.5 kg slips, as Coulomb says).
    pub grip_force_n: f32,
    /// Force limit of each finger's motor (N; default 60: headroom above `grip_force_n` for the
    /// centring spring; also caps the impact when a pad meets an object).
    pub max_force_n: f32,
    /// Speed at which the commanded opening ramps toward its target (m/s of gap; default 0.1:
    /// a jump would hit the object at ~1.8 m/s).
    pub opening_speed_m_s: f32,
    /// Extra solver iterations for the fingers' island (default 4).
    pub finger_extra_solver_iterations: u32,
    /// A closed gripper whose gap is below this holds nothing (m; default 0.005): the
    /// "closed on nothing" test of [`GripReading`].
    pub closed_gap_m: f32,
}

impl Default for GripperConfig {
    /// The preset of the default model ([`GripperModel::default`]: the 2F-140).
    fn default() -> Self {
        Self::preset(GripperModel::default())
    }
}

/// The grippers the sim has presets for ([`GripperConfig::preset`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GripperModel {
    /// Robotiq 2F-85: 85 mm stroke, 20–235 N grip force (Robotiq's figures). The grasp labels
    /// and the shipped network's jaw are this gripper's.
    Robotiq2F85,
    /// Robotiq 2F-140: 140 mm stroke, 10–125 N grip force (Robotiq's figures); longer fingers
    /// on a longer body. The paper's pybullet robot carries it, and it is the default: it takes
    /// every object of the paper's set (the master chef can is 102 mm across) and, planning
    /// again for 85 mm when its stroke finds nothing ([`crate::grasping::attempt::AttemptConfig`]'s
    /// `fallback_openings_m`), grasps the procedural objects at least as well as the 2F-85
    /// (docs/results.md, "The paper's objects").
    #[default]
    Robotiq2F140,
}

impl GripperModel {
    /// Every model.
    pub const ALL: [GripperModel; 2] = [GripperModel::Robotiq2F85, GripperModel::Robotiq2F140];

    /// `2f-85` or `2f-140`.
    pub fn name(self) -> &'static str {
        match self {
            GripperModel::Robotiq2F85 => "2f-85",
            GripperModel::Robotiq2F140 => "2f-140",
        }
    }
}

impl GripperConfig {
    /// The preset of `model`. Strokes and force ranges are Robotiq's published figures; the
    /// per-finger squeeze (40 N, 80 N in all) lies inside both ranges, and each motor's limit
    /// (60 N, 120 N in all) inside the 2F-140's 125 N. Pad sizes and the tool length are
    /// approximations of the real fingers (the 2F-140's are ~15 mm longer, its body ~5 cm
    /// longer from the flange), not datasheet values.
    pub fn preset(model: GripperModel) -> GripperConfig {
        match model {
            GripperModel::Robotiq2F85 => GripperConfig {
                stroke_m: 0.085,
                finger_width_m: lgdm_pointcloud::grasp::label::DEFAULT_FINGER_WIDTH_M,
                finger_length_m: 0.05,
                finger_thickness_m: 0.01,
                finger_density_kg_m3: 8000.0,
                finger_friction: 1.0,
                tool_length_m: 0.15,
                palm_half_width_m: 0.03,
                motor_stiffness_n_m: 1.0e4,
                motor_damping_n_s_m: 200.0,
                grip_force_n: 40.0,
                max_force_n: 60.0,
                opening_speed_m_s: 0.1,
                finger_extra_solver_iterations: 4,
                closed_gap_m: 0.005,
            },
            GripperModel::Robotiq2F140 => GripperConfig {
                stroke_m: 0.14,
                finger_length_m: 0.065,
                tool_length_m: 0.2,
                ..GripperConfig::preset(GripperModel::Robotiq2F85)
            },
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), WorldError> {
        for (field, value) in [
            ("stroke_m", self.stroke_m),
            ("finger_width_m", self.finger_width_m),
            ("finger_length_m", self.finger_length_m),
            ("finger_thickness_m", self.finger_thickness_m),
            ("finger_density_kg_m3", self.finger_density_kg_m3),
            ("palm_half_width_m", self.palm_half_width_m),
            ("motor_stiffness_n_m", self.motor_stiffness_n_m),
            ("grip_force_n", self.grip_force_n),
            ("max_force_n", self.max_force_n),
            ("opening_speed_m_s", self.opening_speed_m_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(WorldError::InvalidConfig {
                    field: format!("gripper.{field}"),
                    reason: format!("{value} must be positive and finite"),
                });
            }
        }
        for (field, value) in [
            ("finger_friction", self.finger_friction),
            ("motor_damping_n_s_m", self.motor_damping_n_s_m),
            ("closed_gap_m", self.closed_gap_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(WorldError::InvalidConfig {
                    field: format!("gripper.{field}"),
                    reason: format!("{value} must be non-negative and finite"),
                });
            }
        }
        if self.grip_force_n > self.max_force_n {
            return Err(WorldError::InvalidConfig {
                field: "gripper.grip_force_n".into(),
                reason: format!(
                    "{} is above max_force_n {}",
                    self.grip_force_n, self.max_force_n
                ),
            });
        }
        if !(self.tool_length_m.is_finite() && self.tool_length_m > self.finger_length_m) {
            return Err(WorldError::InvalidConfig {
                field: "gripper.tool_length_m".into(),
                reason: format!(
                    "{} must exceed finger_length_m {} (the palm sits above the pads)",
                    self.tool_length_m, self.finger_length_m
                ),
            });
        }
        Ok(())
    }

    /// Height of the palm box: from the flange down to the top of the pads (m).
    pub fn palm_height_m(&self) -> f32 {
        self.tool_length_m - 0.5 * self.finger_length_m
    }

    /// Half extent of the palm box along the opening axis (m): the fully open fingers' outer
    /// faces plus 5 mm.
    pub fn palm_half_length_m(&self) -> f32 {
        0.5 * self.stroke_m + self.finger_thickness_m + 0.005
    }

    /// Distance from the pad centre (TCP) to the fingertips along the approach axis (m).
    pub fn tip_from_tcp_m(&self) -> f32 {
        0.5 * self.finger_length_m
    }
}

/// A part of the gripper.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GripperPart {
    /// The palm box.
    Palm,
    /// Finger 0 (on the palm's −x side).
    Finger0,
    /// Finger 1 (on the palm's +x side).
    Finger1,
}

/// What a gripper part touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Contactee {
    /// A dynamic object.
    Object(ObjectHandle),
    /// Fixed scenery (table, basket, floor, pedestal).
    Scenery,
}

/// One pushing contact of the gripper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Touch {
    /// The gripper's part.
    pub part: GripperPart,
    /// What it touches.
    pub other: Contactee,
    /// Normal force over the last step (N): contact impulse / dt.
    pub force_n: f32,
}

/// One finger's contact with an object over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FingerContact {
    /// The finger pushes on the object (a contact with a non-zero impulse).
    pub touching: bool,
    /// Normal force over the last step (N): the pair's contact impulse / dt. With the finger
    /// pads stalled on an object this is [`GripperConfig::grip_force_n`].
    pub force_n: f32,
}

/// What the fingers hold, read from body poses and contacts (see [`Gripper::grip_reading`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GripReading {
    /// Gap between the pads (m), from the body poses.
    pub gap_m: f32,
    /// Each finger's contact with the object.
    pub contacts: [FingerContact; 2],
    /// The gap is below [`GripperConfig::closed_gap_m`]: the fingers closed on nothing (a
    /// "missed" grasp once the gripper was told to close).
    pub closed_on_nothing: bool,
}

impl GripReading {
    /// Both fingers push on the object and the fingers are not closed on nothing.
    pub fn pinching(&self) -> bool {
        !self.closed_on_nothing && self.contacts.iter().all(|c| c.touching)
    }
}

#[derive(Debug, Clone, Copy)]
struct Finger {
    body: RigidBodyHandle,
    collider: ColliderHandle,
    joint: ImpulseJointHandle,
}

/// The gripper: handles into a [`World`] plus the commanded state.
#[derive(Debug, Clone)]
pub struct Gripper {
    config: GripperConfig,
    palm_body: RigidBodyHandle,
    palm_collider: ColliderHandle,
    fingers: [Finger; 2],
    world_from_palm: RPose,
    target_opening_m: f32,
    setpoint_opening_m: f32,
    stalled: bool,
}

fn gripper_groups() -> InteractionGroups {
    InteractionGroups::new(
        GROUP_GRIPPER,
        GROUP_STATIC | GROUP_OBJECT,
        InteractionTestMode::And,
    )
}

impl Gripper {
    /// Builds the palm at `world_from_palm` with the fingers at `opening_m` (clamped to the
    /// stroke) and the motors holding that opening.
    pub fn new(
        world: &mut World,
        config: GripperConfig,
        world_from_palm: &Isometry3<f64>,
        opening_m: f32,
    ) -> Result<Self, WorldError> {
        config.validate()?;
        if !opening_m.is_finite() {
            return Err(WorldError::InvalidConfig {
                field: "opening_m".into(),
                reason: format!("{opening_m} is not finite"),
            });
        }
        let palm_pose = isometry_to_rapier(world_from_palm).ok_or(WorldError::NonFinitePose {
            what: "palm".into(),
        })?;
        let opening = opening_m.clamp(0.0, config.stroke_m);
        let t = config.finger_thickness_m;
        let palm_h = config.palm_height_m();
        let palm_collider = ColliderBuilder::cuboid(
            config.palm_half_length_m(),
            config.palm_half_width_m,
            0.5 * palm_h,
        )
        .translation(RVec::new(0.0, 0.0, -config.tip_from_tcp_m() - 0.5 * palm_h))
        .friction(config.finger_friction)
        .friction_combine_rule(CoefficientCombineRule::Multiply)
        .collision_groups(gripper_groups());
        let (palm_body, palm_collider) = world.physics.insert(
            RigidBodyBuilder::kinematic_position_based().pose(palm_pose),
            palm_collider,
        );
        let mut make_finger = |side: f32| {
            let x = side * 0.5 * (opening + t);
            let pose = palm_pose * RPose::from_translation(RVec::new(x, 0.0, 0.0));
            let body = RigidBodyBuilder::dynamic()
                .pose(pose)
                .additional_solver_iterations(config.finger_extra_solver_iterations as usize);
            let collider = ColliderBuilder::cuboid(
                0.5 * t,
                0.5 * config.finger_width_m,
                0.5 * config.finger_length_m,
            )
            .density(config.finger_density_kg_m3)
            .friction(config.finger_friction)
            .friction_combine_rule(CoefficientCombineRule::Multiply)
            .collision_groups(gripper_groups());
            let (body, collider) = world.physics.insert(body, collider);
            // Joint coordinate = how far the finger's inner face is from the centre.
            let joint = PrismaticJointBuilder::new(RVec::X * side)
                .local_anchor1(RVec::new(side * 0.5 * t, 0.0, 0.0))
                .local_anchor2(RVec::ZERO)
                .limits([0.0, 0.5 * config.stroke_m])
                .motor_model(MotorModel::ForceBased)
                .motor_position(
                    0.5 * opening,
                    config.motor_stiffness_n_m,
                    config.motor_damping_n_s_m,
                )
                .motor_max_force(config.max_force_n)
                .contacts_enabled(false);
            let joint = world
                .physics
                .impulse_joints
                .insert(palm_body, body, joint, true);
            Finger {
                body,
                collider,
                joint,
            }
        };
        let fingers = [make_finger(-1.0), make_finger(1.0)];
        Ok(Self {
            config,
            palm_body,
            palm_collider,
            fingers,
            world_from_palm: palm_pose,
            target_opening_m: opening,
            setpoint_opening_m: opening,
            stalled: false,
        })
    }

    /// Takes the gripper out of `world`: the palm and both fingers, with their colliders and
    /// joints (a free gripper's trial ends so: [`crate::grasping::free_grasp`]).
    pub fn remove(self, world: &mut World) {
        for finger in self.fingers {
            world.physics.remove_body_with_colliders(finger.body, true);
        }
        world
            .physics
            .remove_body_with_colliders(self.palm_body, true);
    }

    /// The palm body and the finger bodies (finger 0 on −x, finger 1 on +x), for the recorder.
    pub(crate) fn bodies(&self) -> (RigidBodyHandle, [RigidBodyHandle; 2]) {
        (self.palm_body, self.fingers.map(|f| f.body))
    }

    /// The config.
    pub fn config(&self) -> &GripperConfig {
        &self.config
    }

    /// Commands the palm pose; the palm moves there at the next step (kinematically, so the
    /// caller moves it smoothly, e.g. along a [`PalmPath`] or the arm's trajectory).
    pub fn set_palm_pose(&mut self, world_from_palm: &Isometry3<f64>) -> Result<(), WorldError> {
        self.world_from_palm =
            isometry_to_rapier(world_from_palm).ok_or(WorldError::NonFinitePose {
                what: "palm".into(),
            })?;
        Ok(())
    }

    /// The commanded palm pose.
    pub fn commanded_palm_pose(&self) -> Isometry3<f64> {
        rapier_to_isometry(&self.world_from_palm)
    }

    /// The palm's pose in the world now.
    pub fn palm_pose(&self, world: &World) -> Isometry3<f64> {
        rapier_to_isometry(world.physics.bodies[self.palm_body].position())
    }

    /// Commands the opening between the pads (m, clamped to `[0, stroke]`); the motors'
    /// set-point ramps toward it at `opening_speed_m_s`. Closing on an object: command 0 and
    /// the motors squeeze with `grip_force_n` each once the pads meet the object.
    pub fn set_opening(&mut self, opening_m: f32) -> Result<(), WorldError> {
        if !opening_m.is_finite() {
            return Err(WorldError::InvalidConfig {
                field: "opening_m".into(),
                reason: format!("{opening_m} is not finite"),
            });
        }
        self.target_opening_m = opening_m.clamp(0.0, self.config.stroke_m);
        Ok(())
    }

    /// The commanded (target) opening (m).
    pub fn target_opening_m(&self) -> f32 {
        self.target_opening_m
    }

    /// The motors' current set-point (m of gap), ramping toward the target.
    pub fn setpoint_opening_m(&self) -> f32 {
        self.setpoint_opening_m
    }

    /// Whether the set-point has reached the target, or the pads stalled on an object while
    /// closing (the set-point then holds the squeeze).
    pub fn opening_settled(&self) -> bool {
        self.setpoint_opening_m == self.target_opening_m || self.stalled
    }

    /// Whether, at the last step, the closing set-point was held by the pads' measured gap (the
    /// pads pressing on something).
    pub fn stalled(&self) -> bool {
        self.stalled
    }

    /// Applies the commands for the coming step: ramps the set-point, sets the motors and the
    /// palm's kinematic target. Called by [`Gripper::step`] (and by the robot before it steps).
    pub(crate) fn apply(&mut self, world: &mut World) {
        let max_delta = self.config.opening_speed_m_s * world.dt_s();
        let previous = self.setpoint_opening_m;
        let error = self.target_opening_m - previous;
        let mut setpoint = if error.abs() <= max_delta {
            self.target_opening_m
        } else {
            previous + error.clamp(-max_delta, max_delta)
        };
        self.stalled = false;
        if setpoint < previous {
            // Closing: at most the squeeze offset inside the measured gap (per finger
            // grip_force / k, so twice that in gap).
            let squeeze_m = 2.0 * self.config.grip_force_n / self.config.motor_stiffness_n_m;
            let floor = self.finger_gap_m(world) - squeeze_m;
            if floor > setpoint {
                setpoint = floor.min(previous);
                self.stalled = true;
            }
        }
        self.setpoint_opening_m = setpoint;
        for finger in &self.fingers {
            if let Some(joint) = world.physics.impulse_joints.get_mut(finger.joint, true) {
                joint.data.set_motor_position(
                    JointAxis::LinX,
                    0.5 * self.setpoint_opening_m,
                    self.config.motor_stiffness_n_m,
                    self.config.motor_damping_n_s_m,
                );
            }
        }
        if let Some(palm) = world.physics.bodies.get_mut(self.palm_body) {
            palm.set_next_kinematic_position(self.world_from_palm);
        }
    }

    /// Applies the commands and steps the world once.
    pub fn step(&mut self, world: &mut World) {
        self.apply(world);
        world.step();
    }

    /// The two fingers' centres in the palm's current frame (m).
    pub fn finger_positions_in_palm_m(&self, world: &World) -> [[f32; 3]; 2] {
        let palm = world.physics.bodies[self.palm_body].position();
        self.fingers.map(|f| {
            let p = world.physics.bodies[f.body].translation();
            palm.inverse_transform_point(p).to_array()
        })
    }

    /// The gap between the pads' inner faces along the palm's x (m), from the body poses.
    pub fn finger_gap_m(&self, world: &World) -> f32 {
        let [p0, p1] = self.finger_positions_in_palm_m(world);
        p1[0] - p0[0] - self.config.finger_thickness_m
    }

    /// Each finger's contact with `object` over the last step.
    pub fn contacts_with(
        &self,
        world: &World,
        object: ObjectHandle,
    ) -> Result<[FingerContact; 2], WorldError> {
        let collider = world.object_collider(object)?;
        let inv_dt = 1.0 / world.dt_s();
        Ok(self.fingers.map(|f| {
            world
                .physics
                .narrow_phase
                .contact_pair(f.collider, collider)
                .map(|pair| {
                    let impulse = pair.total_impulse_magnitude();
                    FingerContact {
                        touching: pair.has_any_active_contact() && impulse > 0.0,
                        force_n: impulse * inv_dt,
                    }
                })
                .unwrap_or_default()
        }))
    }

    /// Every pushing contact of the palm and fingers with objects and scenery over the last
    /// step, in a fixed order (palm, finger 0, finger 1; then rapier's pair order).
    pub fn touches(&self, world: &World) -> Vec<Touch> {
        let inv_dt = 1.0 / world.dt_s();
        let parts = [
            (GripperPart::Palm, self.palm_collider),
            (GripperPart::Finger0, self.fingers[0].collider),
            (GripperPart::Finger1, self.fingers[1].collider),
        ];
        let mut out = Vec::new();
        for (part, collider) in parts {
            for pair in world.physics.narrow_phase.contact_pairs_with(collider) {
                let impulse = pair.total_impulse_magnitude();
                if !(pair.has_any_active_contact() && impulse > 0.0) {
                    continue;
                }
                let other = if pair.collider1 == collider {
                    pair.collider2
                } else {
                    pair.collider1
                };
                let other = if let Some(object) = world.object_of_collider(other) {
                    Contactee::Object(object)
                } else if world.is_scenery(other) {
                    Contactee::Scenery
                } else {
                    continue;
                };
                out.push(Touch {
                    part,
                    other,
                    force_n: impulse * inv_dt,
                });
            }
        }
        out
    }

    /// The colliders of the palm and the two fingers, in [`Gripper::touches`]' order (for
    /// queries inside the crate).
    pub(crate) fn part_colliders(&self) -> [(GripperPart, ColliderHandle); 3] {
        [
            (GripperPart::Palm, self.palm_collider),
            (GripperPart::Finger0, self.fingers[0].collider),
            (GripperPart::Finger1, self.fingers[1].collider),
        ]
    }

    /// The gap and both fingers' contacts with `object` now.
    pub fn grip_reading(
        &self,
        world: &World,
        object: ObjectHandle,
    ) -> Result<GripReading, WorldError> {
        let gap_m = self.finger_gap_m(world);
        Ok(GripReading {
            gap_m,
            contacts: self.contacts_with(world, object)?,
            closed_on_nothing: gap_m < self.config.closed_gap_m,
        })
    }

    /// The sum of both fingers' normal forces on `object` (N).
    pub fn grip_force_n(&self, world: &World, object: ObjectHandle) -> Result<f32, WorldError> {
        let [a, b] = self.contacts_with(world, object)?;
        Ok(a.force_n + b.force_n)
    }

    /// Whether the fingers or palm state is NaN or infinite.
    pub fn check_finite(&self, world: &World) -> Result<(), WorldError> {
        for (i, f) in self.fingers.iter().enumerate() {
            let body = &world.physics.bodies[f.body];
            if !(body.translation().is_finite()
                && body.rotation().is_finite()
                && body.linvel().is_finite())
            {
                return Err(WorldError::NonFiniteState {
                    object: format!("finger {i}"),
                    step: world.steps(),
                });
            }
        }
        Ok(())
    }
}

/// A straight palm move from one pose to another (translation linear, rotation by slerp),
/// timed with a trapezoidal speed profile: accelerate at `accel_m_s2`, cruise at `speed_m_s`,
/// decelerate to rest.
///
/// ```
/// use lgdm_sim::robot::gripper::PalmPath;
/// use nalgebra::Isometry3;
/// let a = Isometry3::translation(0.0, 0.0, 1.0);
/// let b = Isometry3::translation(0.0, 0.0, 1.2);
/// let path = PalmPath::new(&a, &b, 0.1, 1.0).unwrap();
/// assert!((path.duration_s() - 2.1).abs() < 1e-9); // 0.2 m at 0.1 m/s plus the ramps
/// assert_eq!(path.pose_at(10.0).translation.vector.z, 1.2);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PalmPath {
    from: Isometry3<f64>,
    to: Isometry3<f64>,
    length_m: f64,
    speed_m_s: f64,
    accel_m_s2: f64,
    t_accel_s: f64,
    t_cruise_s: f64,
}

impl PalmPath {
    /// A rotation counts as this many metres per radian of path, for timing.
    pub const ROTATION_LENGTH_M_PER_RAD: f64 = 0.1;

    /// The path from `from` to `to` at most `speed_m_s` and `accel_m_s2`.
    pub fn new(
        from: &Isometry3<f64>,
        to: &Isometry3<f64>,
        speed_m_s: f64,
        accel_m_s2: f64,
    ) -> Result<Self, WorldError> {
        for (field, value) in [("speed_m_s", speed_m_s), ("accel_m_s2", accel_m_s2)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(WorldError::InvalidConfig {
                    field: format!("palm_path.{field}"),
                    reason: format!("{value} must be positive and finite"),
                });
            }
        }
        for (what, pose) in [("palm path start", from), ("palm path goal", to)] {
            if isometry_to_rapier(pose).is_none() {
                return Err(WorldError::NonFinitePose { what: what.into() });
            }
        }
        let distance = (to.translation.vector - from.translation.vector).norm();
        let angle = from.rotation.angle_to(&to.rotation);
        let length_m = distance.max(angle * Self::ROTATION_LENGTH_M_PER_RAD);
        let (speed, t_accel, t_cruise) = if length_m * accel_m_s2 <= speed_m_s * speed_m_s {
            let peak = (length_m * accel_m_s2).sqrt();
            (peak, peak / accel_m_s2, 0.0)
        } else {
            let t_accel = speed_m_s / accel_m_s2;
            (
                speed_m_s,
                t_accel,
                (length_m - speed_m_s * t_accel) / speed_m_s,
            )
        };
        Ok(Self {
            from: *from,
            to: *to,
            length_m,
            speed_m_s: speed,
            accel_m_s2,
            t_accel_s: t_accel,
            t_cruise_s: t_cruise,
        })
    }

    /// Total time (s).
    pub fn duration_s(&self) -> f64 {
        2.0 * self.t_accel_s + self.t_cruise_s
    }

    /// The goal pose.
    pub fn goal(&self) -> Isometry3<f64> {
        self.to
    }

    /// The pose at time `t_s` (clamped to the path; NaN gives the start).
    pub fn pose_at(&self, t_s: f64) -> Isometry3<f64> {
        let total = self.duration_s();
        if self.length_m <= 0.0 || t_s >= total {
            return self.to;
        }
        let t = if t_s.is_nan() { 0.0 } else { t_s.max(0.0) };
        let (a, v, ta) = (self.accel_m_s2, self.speed_m_s, self.t_accel_s);
        let s = if t < ta {
            0.5 * a * t * t
        } else if t < ta + self.t_cruise_s {
            0.5 * a * ta * ta + v * (t - ta)
        } else {
            let r = total - t;
            self.length_m - 0.5 * a * r * r
        };
        let f = (s / self.length_m).clamp(0.0, 1.0);
        let translation = self
            .from
            .translation
            .vector
            .lerp(&self.to.translation.vector, f);
        let rotation = self
            .from
            .rotation
            .try_slerp(&self.to.rotation, f, 1e-12)
            .unwrap_or(self.to.rotation);
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }
}

/// A top-down palm pose: pads pointing down (−Z world), opening along `(cos yaw, sin yaw, 0)`,
/// the pad centre at `position_m` (the same convention as [`crate::robot::ik::TopDownGrasp`]).
pub fn top_down_palm_pose(position_m: [f64; 3], yaw_rad: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(position_m)),
        crate::robot::ik::top_down_rotation(yaw_rad),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;

    #[test]
    fn config_validation_names_the_field() {
        GripperConfig::default().validate().unwrap();
        let cfg = GripperConfig {
            max_force_n: 0.0,
            ..GripperConfig::default()
        };
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "gripper.max_force_n"
        ));
        let cfg = GripperConfig {
            tool_length_m: 0.02,
            ..GripperConfig::default()
        };
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "gripper.tool_length_m"
        ));
        let cfg = GripperConfig {
            finger_friction: f32::NAN,
            ..GripperConfig::default()
        };
        let err = cfg.validate().unwrap_err();
        assert!(err.to_string().contains("gripper.finger_friction"), "{err}");
        let json = serde_json::to_string(&GripperConfig::default()).unwrap();
        assert_eq!(
            serde_json::from_str::<GripperConfig>(&json).unwrap(),
            GripperConfig::default()
        );
    }

    #[test]
    fn bad_commands_are_errors() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let pose = top_down_palm_pose([0.0, -0.6, 1.0], 0.0);
        let mut g = Gripper::new(&mut world, GripperConfig::default(), &pose, 0.05).unwrap();
        assert!(g.set_opening(f32::NAN).is_err());
        let mut bad = pose;
        bad.translation.vector.x = f64::NAN;
        assert!(g.set_palm_pose(&bad).is_err());
        assert!(Gripper::new(&mut world, GripperConfig::default(), &bad, 0.05).is_err());
        g.set_opening(1.0).unwrap();
        assert_eq!(g.target_opening_m(), GripperConfig::default().stroke_m);
        assert!(PalmPath::new(&pose, &pose, 0.0, 1.0).is_err());
    }

    #[test]
    fn spawned_gap_matches_opening_and_ramp_is_limited() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let pose = top_down_palm_pose([0.0, -0.6, 1.0], 0.3);
        let mut g = Gripper::new(&mut world, GripperConfig::default(), &pose, 0.06).unwrap();
        assert!((g.finger_gap_m(&world) - 0.06).abs() < 1e-5);
        g.set_opening(0.0).unwrap();
        g.step(&mut world);
        let dt = world.dt_s();
        assert!((g.setpoint_opening_m() - (0.06 - 0.1 * dt)).abs() < 1e-6);
    }

    #[test]
    fn palm_path_is_monotone_and_ends_at_goal() {
        let a = top_down_palm_pose([0.0, -0.5, 1.2], 0.0);
        let b = top_down_palm_pose([0.1, -0.5, 0.9], 0.5);
        let path = PalmPath::new(&a, &b, 0.1, 1.0).unwrap();
        let mut prev = 0.0;
        for i in 0..=100 {
            let t = path.duration_s() * f64::from(i) / 100.0;
            let p = path.pose_at(t);
            let d = (p.translation.vector - a.translation.vector).norm();
            assert!(d + 1e-12 >= prev);
            prev = d;
        }
        assert_eq!(path.pose_at(path.duration_s()), b);
    }
}
