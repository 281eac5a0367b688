//! Tabletop simulation: a kinematic arm and a parallel-jaw gripper that recognise, grasp and place
//! objects. The modules sit in folders by concept, each folder using only the ones listed before
//! it (`tests/module_graph.rs` checks that no folder, and no file inside one, is part of a cycle):
//!
//! - [`timing`]: where an attempt's wall time goes (render, perception, source, planning,
//!   physics, recognition), kept apart from the deterministic records.
//! - [`physics`]: the rapier3d world and its objects.
//!   - [`physics::world`]: the [`World`] — the reference table (top at z = 0.785 m), two
//!     baskets, a floor, dynamic objects built from the pointcloud crate's meshes; spawn, drop,
//!     step, settle, read poses back for the renderer.
//!   - [`physics::config`]: every constant of the world ([`WorldConfig`]), validated once.
//!   - [`physics::error`]: its errors ([`WorldError`]).
//!   - [`physics::object`]: an object's handle ([`ObjectHandle`]) and its collider drawn in the
//!     mesh's colours.
//!   - [`physics::drop_region`]: drop regions (uniform poses on the table).
//!   - [`physics::shapes`] (on [`physics::hull`]): objects' colliders — a convex decomposition
//!     that keeps openings and handles (default), or the mesh's convex hull.
//!   - [`physics::hull`]: thinned convex hulls, the extreme points of dense meshes, how solid a
//!     mesh is.
//!   - [`physics::measure`]: an object's narrowest width and solidity (`wider_than_gripper`).
//!   - `physics::rapier` (crate-private): rapier's math types at the boundary, the pose
//!     conversions, the collision groups.
//! - [`robot`]: the [`Robot`] — the arm's links as kinematic bodies posed by forward kinematics,
//!   the gripper at the tool frame, trajectories followed in sim time with optional
//!   stop-on-contact.
//!   - [`robot::arm`]: the kinematic model of a UR-class arm ([`ArmModel::ur5e`],
//!     [`ArmModel::ur5_cb3`]), forward kinematics of every link and the tool, the Jacobian.
//!   - [`robot::ik`]: inverse kinematics as a sequence of QPs with joint limits (clarabel), for
//!     full poses and top-down grasps; unreachable targets are typed errors.
//!   - [`robot::trajectory`]: joint trajectories timed within the speed and acceleration limits,
//!     and straight-line tool moves.
//!   - [`robot::gripper`]: a kinematic palm and two dynamic, force-limited fingers on prismatic
//!     joints (2F-140 and 2F-85 presets); the gap read from body poses, contacts per finger.
//! - [`perception`]: segmentation of the overview, one object-centred crop per object, crop
//!   grasps back to top-down grasps in the world.
//!   - [`perception::camera`]: RGB-D frames of the world with the pointcloud crate's renderer —
//!     the overview camera and a per-object close-up at the dataset's grasp-camera scale.
//! - [`grasping`]: from a crop to a judged grasp.
//!   - [`grasping::source`]: the [`grasping::source::GraspSource`] trait, the `analytic`,
//!     `random` and fixed sources, the built-in ones by name, how proposals are checked.
//!   - [`grasping::proposals`]: how the robot asks a source (fallback openings, the proposal
//!     check against the close-up's depth).
//!   - [`grasping::attempt`]: one attempt (approach, guarded descent, close, lift, judge, carry,
//!     release, judge) with strict and contact-only success and a failure reason; its parts are
//!     private files: `config`, `plan`, `motion` (the cell and its moves), `verdict` (contacts
//!     and the criterion), `execute` (the phases).
//!   - [`grasping::free_grasp`]: a grasp tried by the gripper alone, judged the same way.
//! - [`recognition`]: recognition in the loop.
//!   - [`recognition::recognizer`]: the dual memory's first guess with a confidence, the
//!     simulated teacher's lessons, replay.
//!   - [`recognition::views`]: an object's views on the dataset's viewing geometry.
//!   - [`recognition::encoder`]: views → features ([`recognition::encoder::ViewEncoder`], GOOD).
//!   - [`recognition::labels`]: category and instance names by id.
//!   - [`recognition::config`], [`recognition::error`]: its constants and errors.
//!   - [`recognition::model`]: the model a pick-and-place run starts from and leaves.
//! - [`tasks`]: what the rounds ask of the robot.
//!   - [`tasks::scenario`]: isolated, packed, pile and scattered tables.
//!   - [`tasks::packing`]: each object to the basket of the category it is recognised as.
//!   - [`tasks::arrival`]: categories arriving over time, and the end-of-run evaluation.
//! - [`run`]: a run from its spec to its run directory.
//!   - [`run::config`]: every constant of a run ([`run::config::SimConfig`], TOML).
//!   - [`run::spec`]: what a run is ([`run::spec::RunSpec`]), validated once.
//!   - [`run::error`]: every error of a run ([`run::error::SimError`]).
//!   - [`run::objects`]: where a job's objects come from (procedural or meshes).
//!   - [`run::runner`]: playing the rounds, calling a [`run::observe::RunObserver`] at each
//!     event; [`run::observe`] is that seam.
//!   - [`run::state`]: where a run is after its finished rounds (checkpoints, resume).
//!   - [`run::results`]: attempt and round records and the summary — everything `results.json`
//!     holds; [`run::report`] the same as text (`summary.txt`); [`run::plots`] its PNGs.
//!   - [`run::run_dir`]: the run directory (ownership, lock, atomic files, checkpoints).
//!   - [`run::job`]: the binary's jobs as one library call each — grasp, pick-and-place,
//!     packing — from a setup to a written run directory.
//!   - [`run::record`]: optional recording of rounds for Foxglove (MCAP) and PNG storyboards;
//!     [`run::captions`] says in words what happened.
//! - [`datagen`]: data made in the robot's world.
//!   - [`datagen::grasp_data`]: grasp training data tried by the free gripper
//!     (`lgdm sim grasp-data`).
//!   - [`datagen::object_sets`]: the paper's YCB objects laid out for `--meshes`.
//!   - [`datagen::ycb_dataset`]: the `ycb` dataset preset (the YCB meshes in categories).
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
//! The physics side (see [`physics::world`], [`robot::gripper`] and [`robot`] for more):
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
