//! Tabletop simulation: a kinematic arm and a parallel-jaw gripper that recognise, grasp and place
//! objects: the arm, the physics world, the gripper, the cameras and perception, grasp sources,
//! one honestly judged grasp attempt, the reference scenarios and runs with their results.
//!
//! - [`arm`]: the kinematic model of a UR-class arm ([`ArmModel::ur5e`], [`ArmModel::ur5_cb3`]),
//!   forward kinematics of every link and the tool, the geometric Jacobian.
//! - [`ik`]: inverse kinematics as a sequence of QPs with joint limits (clarabel), for full
//!   poses and top-down grasps; unreachable targets are typed errors.
//! - [`trajectory`]: joint trajectories timed within the speed and acceleration limits, and
//!   straight-line tool moves (approach, descend, lift).
//! - [`world`]: the rapier3d physics world — the reference table (top at z = 0.785 m), two
//!   baskets, a floor, and dynamic objects built from the pointcloud crate's meshes (their
//!   [`shapes`]); spawn, drop at a random pose, settle, read poses back for the renderer.
//! - [`gripper`]: a kinematic palm and two dynamic, force-limited fingers on prismatic joints;
//!   opening commands ramp, the gap is read from body poses, contacts per finger.
//! - [`robot`]: the arm's links as kinematic bodies posed by forward kinematics, the gripper at
//!   the tool frame, trajectories followed in sim time with optional stop-on-contact.
//! - [`camera`]: RGB-D frames of the world with the pointcloud crate's renderer — the
//!   reference overview camera and a per-object close-up at the dataset's grasp-camera scale;
//!   every constant in [`camera::CameraConfig`].
//! - [`perception`]: segmentation of the overview, one object-centred crop per object, crop
//!   grasps back to top-down grasps in the world.
//! - [`source`]: the [`source::GraspSource`] trait and the `analytic` and `random` sources.
//! - [`recognize`]: recognition in the loop — the object's views from the dataset's viewing
//!   geometry, the dataset's GOOD features, the dual memory's first guess with a confidence, the
//!   simulated teacher's lessons and replay.
//! - [`attempt`]: one attempt (approach, guarded descent, close, lift, judge, carry, release,
//!   judge) with strict and contact-only success and a failure reason; [`timing`] adds up
//!   where its wall time goes.
//! - [`scenario`]: isolated, packed, pile and scattered tables.
//! - [`shapes`] (on [`hull`]): objects' colliders — a convex decomposition that keeps openings and handles
//!   (default), or the mesh's convex hull.
//! - [`config`]: every constant of a run ([`config::SimConfig`]); [`spec`]: what a run is
//!   ([`spec::RunSpec`]), validated once; its errors.
//! - [`runner`]: playing the rounds, calling an [`observe::RunObserver`] at each event;
//!   [`packing`] and [`arrival`] are the policies pick-and-place can add.
//! - [`results`]: attempt and round records, the summary (rates with Wilson intervals, per
//!   category, per failure reason), everything `results.json` holds; [`report`] the same as
//!   text (`summary.txt`).
//! - [`model`]: the model a pick-and-place run starts from and leaves, with its record.
//! - [`run_dir`]: the run directory (ownership, lock, atomic files).
//! - [`job`]: the binary's jobs as one library call each — grasp, pick-and-place, packing —
//!   from a setup to a written run directory.
//! - [`record`]: optional recording of rounds for Foxglove — one MCAP per round (`/tf` of every
//!   body, the scene, camera images, the chosen grasp, events; sim time, so same seed → same
//!   bytes) and a PNG storyboard per round; [`captions`] says in words what happened.
//!
//! Grasps succeed or fail by contact and friction only: nothing is ever welded, attached or
//! teleported. Physics is single-threaded and deterministic: same inputs, same bits.
//!
//! Lengths are metres, angles radians, times seconds; frames are named `a_from_b`
//! (`world_from_tool` maps tool coordinates into the world). The world is Z up.
//!
//! ```
//! use lgdm_sim::robot::arm::ArmModel;
//! use lgdm_sim::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};
//! use lgdm_sim::robot::trajectory::JointTrajectory;
//! let arm = ArmModel::ur5e();
//! let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
//! let grasp = TopDownGrasp::new([0.5, -0.1, 0.2], 0.4);
//! let q = ik.solve(&IkTarget::TopDown(grasp), &arm.home_rad).unwrap().joints_rad;
//! let move_there = JointTrajectory::point_to_point(&arm, &arm.home_rad, &q).unwrap();
//! assert_eq!(move_there.sample(move_there.duration_s()), q);
//! ```
//!
//! The physics side (see [`world`], [`gripper`] and [`robot`] for more):
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! use lgdm_sim::robot::gripper::{Gripper, GripperConfig, GripperModel, top_down_palm_pose};
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let top_z = world.config().table.top_z_m();
//! let cube = Mesh::cuboid([0.0, 0.0, 0.025], [0.05; 3], [200, 40, 40]);
//! let pose = lgdm_pointcloud::math::translation([0.05, -0.52, top_z]);
//! let cube = world.spawn_object("cube", &cube, &pose).unwrap();
//! world.settle();
//! // The 2F-85's pads around the cube (its 5 cm fingers end 5 mm above the table), closing.
//! let at = top_down_palm_pose([0.05, -0.52, f64::from(top_z) + 0.03], 0.0);
//! let g = GripperConfig::preset(GripperModel::Robotiq2F85);
//! let mut gripper = Gripper::new(&mut world, g, &at, 0.085).unwrap();
//! gripper.set_opening(0.0).unwrap();
//! while !gripper.opening_settled() {
//!     gripper.step(&mut world);
//! }
//! let grip = gripper.grip_reading(&world, cube).unwrap();
//! assert!(grip.pinching() && (grip.gap_m - 0.05).abs() < 2e-3);
//! ```

#![warn(missing_docs)]

pub mod datagen;
pub mod grasping;
pub mod perception;
pub mod physics;
pub mod recognition;
pub mod robot;
pub mod run;
pub mod tasks;
pub mod timing;

pub use physics::config::WorldConfig;
pub use physics::error::WorldError;
pub use physics::object::ObjectHandle;
pub use physics::world::World;
pub use robot::arm::{ArmModel, ArmPose, Joints};
pub use robot::gripper::{GripReading, Gripper, GripperConfig, PalmPath};
pub use robot::ik::{IkConfig, IkError, IkSolution, IkSolver, IkTarget, TopDownGrasp};
pub use robot::trajectory::{JointTrajectory, LinearMove, MotionError, plan_linear_move};
pub use robot::{FollowOptions, FollowReport, Robot, RobotConfig, RobotError};
