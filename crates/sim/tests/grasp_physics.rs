//! Physics contract of the gripper and world: a box narrower than the stroke is held through a
//! 20 cm lift and 1 s hold; a box wider than the stroke, or a long box closed along its length,
//! is not grasped (and a guarded descent stops on the first contact); friction 0.05 slips where
//! Coulomb says; a gripper closed on nothing reads "missed"; dropped objects settle on the table
//! (finite, no sinking > 2 mm, no tunnelling); same seed and commands give bit-identical poses.
//!
//! Run in release (`cargo test -p lgdm-sim --release --test grasp_physics`): physics in a debug
//! build is two orders of magnitude slower. The gripper is driven directly (a floating palm on
//! straight [`PalmPath`]s) except in the arm tests, which drive it through [`Robot`].

use lgdm_pointcloud::math::{Pose, rotation_z, transform_point, translation};
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::objects::{CATEGORIES, procedural_object};
use lgdm_sim::physics::config::{ObjectMaterial, WorldConfig};
use lgdm_sim::physics::drop_region::DropRegion;
use lgdm_sim::physics::object::ObjectHandle;
use lgdm_sim::physics::world::World;
use lgdm_sim::robot::gripper::{
    Gripper, GripperConfig, GripperModel, PalmPath, top_down_palm_pose,
};
use lgdm_sim::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};
use lgdm_sim::robot::trajectory::{JointTrajectory, LinearMove, plan_linear_move};
use lgdm_sim::robot::{FollowOptions, Robot, RobotConfig};
use nalgebra::{Isometry3, Point3, Translation3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Table top (m).
const TOP: f32 = 0.785;
/// Where boxes are placed: the reference camera target.
const SPOT: [f32; 2] = [0.05, -0.52];
/// Palm speed and acceleration of the scripted moves (m/s, m/s²).
const SPEED: f64 = 0.1;
const ACCEL: f64 = 1.0;

fn box_mesh(size_m: [f32; 3]) -> Mesh {
    Mesh::cuboid([0.0, 0.0, 0.5 * size_m[2]], size_m, [180, 60, 40])
}

/// Lowest point of the object's mesh in the world (m).
fn lowest_z(world: &World, h: ObjectHandle) -> f32 {
    let pose = world.object_pose(h).unwrap();
    world
        .object_mesh(h)
        .unwrap()
        .vertices
        .iter()
        .map(|v| transform_point(&pose, *v)[2])
        .fold(f32::INFINITY, f32::min)
}

/// Lowest point of the object's collider (its simplified hull) in the world (m).
fn lowest_hull_z(world: &World, h: ObjectHandle) -> f32 {
    let pose = world.object_pose(h).unwrap();
    world
        .object_hull_points_m(h)
        .unwrap()
        .iter()
        .map(|v| transform_point(&pose, *v)[2])
        .fold(f32::INFINITY, f32::min)
}

/// One scripted close-and-lift with a floating gripper.
#[derive(Debug, Clone)]
struct Trial {
    box_size_m: [f32; 3],
    box_yaw_rad: f32,
    material: ObjectMaterial,
    grasp_yaw_rad: f64,
    gripper: GripperConfig,
    /// No object at all: close on nothing.
    empty: bool,
}

impl Trial {
    fn cube(side_m: f32) -> Self {
        Self {
            box_size_m: [side_m; 3],
            box_yaw_rad: 0.0,
            material: ObjectMaterial {
                density_kg_m3: 1000.0,
                ..ObjectMaterial::default()
            },
            grasp_yaw_rad: 0.0,
            gripper: GripperConfig::preset(GripperModel::Robotiq2F85),
            empty: false,
        }
    }
}

#[derive(Debug, Clone)]
struct Outcome {
    mass_kg: f32,
    rest_z: f32,
    rest_lowest_z: f32,
    planned_grasp_z: f64,
    stopped_on_contact: bool,
    palm_z_after_descent: f64,
    lowest_z_during_descent_and_close: f32,
    gap_after_close_m: f32,
    grip_force_after_close_n: f32,
    both_touching_after_close: bool,
    closed_on_nothing_after_close: bool,
    rise_after_lift_m: f32,
    rise_after_hold_m: f32,
    gap_after_hold_m: f32,
    both_touching_after_hold: bool,
    /// The object's centre in the palm frame after the hold (m).
    object_in_palm_after_hold: [f32; 3],
    final_pose: Pose,
    steps: u64,
}

/// Steps the palm along `path` in sim time; with `guarded`, stops after the first step in which
/// the gripper pushes on anything. Returns whether it stopped early. Calls `each` every step.
fn run_path(
    world: &mut World,
    gripper: &mut Gripper,
    path: &PalmPath,
    guarded: bool,
    mut each: impl FnMut(&World),
) -> bool {
    let dt = f64::from(world.dt_s());
    let steps = (path.duration_s() / dt).ceil() as u32;
    for k in 1..=steps {
        let t = (f64::from(k) * dt).min(path.duration_s());
        gripper.set_palm_pose(&path.pose_at(t)).unwrap();
        gripper.step(world);
        each(world);
        if guarded && !gripper.touches(world).is_empty() {
            return true;
        }
    }
    false
}

fn run(trial: &Trial) -> Outcome {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let [sx, sy, sz] = trial.box_size_m;
    let object_pose = translation([SPOT[0], SPOT[1], TOP]) * rotation_z(trial.box_yaw_rad);
    let object = if trial.empty {
        // A far-away object so the readings have something to refer to.
        let h = world
            .spawn_object_with(
                "far",
                &box_mesh([0.05; 3]),
                &translation([-0.4, -0.85, TOP]),
                &trial.material,
            )
            .unwrap();
        world.settle();
        h
    } else {
        let h = world
            .spawn_object_with(
                "box",
                &box_mesh([sx, sy, sz]),
                &object_pose,
                &trial.material,
            )
            .unwrap();
        assert!(world.settle().settled);
        h
    };
    let mass_kg = world.object_mass_kg(object).unwrap();
    let rest_z = world.object_pose(object).unwrap().translation.z;
    let rest_lowest_z = lowest_z(&world, object);
    let half_pad = f64::from(trial.gripper.tip_from_tcp_m());
    let center_z = if trial.empty {
        f64::from(TOP) + 0.025
    } else {
        f64::from(rest_z) + 0.5 * f64::from(sz)
    };
    let grasp_z = center_z.max(f64::from(TOP) + half_pad + 0.005);
    let [x, y] = SPOT.map(f64::from);
    let above = top_down_palm_pose([x, y, grasp_z + 0.15], trial.grasp_yaw_rad);
    let at = top_down_palm_pose([x, y, grasp_z], trial.grasp_yaw_rad);
    let mut gripper = Gripper::new(&mut world, trial.gripper.clone(), &above, 0.085).unwrap();
    for _ in 0..12 {
        gripper.step(&mut world);
    }
    // Descend, guarded.
    let mut lowest = f32::INFINITY;
    let descent = PalmPath::new(&above, &at, SPEED, ACCEL).unwrap();
    let stopped_on_contact = run_path(&mut world, &mut gripper, &descent, true, |w| {
        lowest = lowest.min(lowest_z(w, object));
    });
    let palm_z_after_descent = gripper.commanded_palm_pose().translation.vector.z;
    // Close: ramp the set-point to 0, then let the squeeze settle for 0.2 s.
    gripper.set_opening(0.0).unwrap();
    let mut guard = 0;
    while !gripper.opening_settled() && guard < 2000 {
        gripper.step(&mut world);
        lowest = lowest.min(lowest_z(&world, object));
        guard += 1;
    }
    for _ in 0..48 {
        gripper.step(&mut world);
        lowest = lowest.min(lowest_z(&world, object));
    }
    let reading = gripper.grip_reading(&world, object).unwrap();
    let grip_force_after_close_n = gripper.grip_force_n(&world, object).unwrap();
    // Lift 20 cm, then hold 1 s.
    let grasped_at = gripper.commanded_palm_pose();
    let mut lifted = grasped_at;
    lifted.translation.vector.z += 0.2;
    let lift = PalmPath::new(&grasped_at, &lifted, SPEED, ACCEL).unwrap();
    run_path(&mut world, &mut gripper, &lift, false, |_| {});
    let rise_after_lift_m = world.object_pose(object).unwrap().translation.z - rest_z;
    for _ in 0..240 {
        gripper.step(&mut world);
    }
    world.check_finite().unwrap();
    gripper.check_finite(&world).unwrap();
    let final_pose = world.object_pose(object).unwrap();
    let hold = gripper.grip_reading(&world, object).unwrap();
    let com = world.object_center_of_mass_m(object).unwrap();
    let palm = gripper.palm_pose(&world);
    let in_palm = palm.inverse_transform_point(&Point3::new(
        f64::from(com[0]),
        f64::from(com[1]),
        f64::from(com[2]),
    ));
    Outcome {
        mass_kg,
        rest_z,
        rest_lowest_z,
        planned_grasp_z: grasp_z,
        stopped_on_contact,
        palm_z_after_descent,
        lowest_z_during_descent_and_close: lowest,
        gap_after_close_m: reading.gap_m,
        grip_force_after_close_n,
        both_touching_after_close: reading.contacts.iter().all(|c| c.touching),
        closed_on_nothing_after_close: reading.closed_on_nothing,
        rise_after_lift_m,
        rise_after_hold_m: final_pose.translation.z - rest_z,
        gap_after_hold_m: hold.gap_m,
        both_touching_after_hold: hold.pinching(),
        object_in_palm_after_hold: [in_palm.x as f32, in_palm.y as f32, in_palm.z as f32],
        final_pose,
        steps: world.steps(),
    }
}

/// The grasp held through the lift and the hold, centred between the pads.
fn assert_held(o: &Outcome, width_m: f32, what: &str) {
    assert!(
        !o.stopped_on_contact,
        "{what}: descent stopped early: {o:#?}"
    );
    assert!(
        o.both_touching_after_close && !o.closed_on_nothing_after_close,
        "{what}: not pinched after closing: {o:#?}"
    );
    // Rises with the palm: 0.2 m of lift, less than 5 mm of slip over lift + 1 s hold.
    assert!(o.rise_after_lift_m > 0.195, "{what}: {o:#?}");
    assert!(
        o.rise_after_hold_m > 0.195,
        "{what}: slipped during the hold: {o:#?}"
    );
    assert!(o.both_touching_after_hold, "{what}: {o:#?}");
    // Gap = box width: the pads press on the faces, not sunk into the box.
    assert!(
        (o.gap_after_hold_m - width_m).abs() < 2e-3,
        "{what}: gap {} vs width {width_m}: {o:#?}",
        o.gap_after_hold_m
    );
    // Between the fingers: centred along the opening axis within 2 mm, within the pad width.
    let [px, py, pz] = o.object_in_palm_after_hold;
    assert!(
        px.abs() < 2e-3 && py.abs() < 0.01 && pz.abs() < 0.03,
        "{what}: {o:#?}"
    );
}

/// Not grasped: the object is (about) where it rested after the lift and hold.
fn assert_not_held(o: &Outcome, what: &str) {
    assert!(
        o.rise_after_hold_m < 0.01,
        "{what}: object rose {} m: {o:#?}",
        o.rise_after_hold_m
    );
    assert!(!o.both_touching_after_hold, "{what}: {o:#?}");
}

#[test]
fn narrow_box_is_held_through_lift_and_one_second_hold() {
    let trial = Trial::cube(0.05);
    let o = run(&trial);
    assert!((o.mass_kg - 0.125).abs() < 1e-3, "{o:#?}");
    assert_held(&o, 0.05, "5 cm cube");
    // The squeeze is the configured grip force on each side (contact impulse / dt).
    let limit = 2.0 * trial.gripper.grip_force_n;
    assert!(
        (o.grip_force_after_close_n - limit).abs() < 0.05 * limit,
        "grip force {} vs {limit}: {o:#?}",
        o.grip_force_after_close_n
    );
    // Yawed box, jaws rotated to match.
    let yawed = Trial {
        box_yaw_rad: 0.5,
        grasp_yaw_rad: 0.5,
        ..Trial::cube(0.05)
    };
    assert_held(&run(&yawed), 0.05, "yawed 5 cm cube");
}

#[test]
fn box_wider_than_the_stroke_is_not_grasped_and_descent_stops_on_contact() {
    let trial = Trial {
        box_size_m: [0.12, 0.06, 0.05],
        ..Trial::cube(0.05)
    };
    let o = run(&trial);
    assert_not_held(&o, "12 cm box");
    // The fingers landed on the top face: the guarded descent stopped there, about a pad half
    // length above the top rather than at the planned grasp height…
    assert!(o.stopped_on_contact, "{o:#?}");
    let top = f64::from(o.rest_z) + 0.05;
    assert!(
        (o.palm_z_after_descent - (top + 0.025)).abs() < 0.01,
        "palm stopped at {} for a top at {top}: {o:#?}",
        o.palm_z_after_descent
    );
    assert!(o.palm_z_after_descent > o.planned_grasp_z + 0.02, "{o:#?}");
    // …and never drove the box into the table.
    assert!(
        o.lowest_z_during_descent_and_close > o.rest_lowest_z - 2e-3,
        "box pushed {} m into the table: {o:#?}",
        o.rest_lowest_z - o.lowest_z_during_descent_and_close
    );
    // Closed on the top face: nothing between the pads.
    assert!(o.closed_on_nothing_after_close, "{o:#?}");
}

#[test]
fn fingers_along_the_long_axis_of_a_long_box_fail_and_across_it_hold() {
    // 20 cm along x, 5 cm across; jaws opening along x close along the 20 cm length.
    let along = Trial {
        box_size_m: [0.2, 0.05, 0.05],
        ..Trial::cube(0.05)
    };
    let o = run(&along);
    assert_not_held(&o, "closing along the 20 cm length");
    assert!(o.stopped_on_contact, "{o:#?}");
    // Control: the same box with the jaws turned 90° closes across its 5 cm width and holds.
    let across = Trial {
        grasp_yaw_rad: std::f64::consts::FRAC_PI_2,
        ..along
    };
    assert_held(&run(&across), 0.05, "closing across the 5 cm width");
}

#[test]
fn low_friction_slips_during_the_lift() {
    // A 0.5 kg 5 cm box: with μ = 0.05 (pads 1.0 × object 0.05) the 2 × 40 N squeeze holds at
    // most 2·μ·F = 4 N < m·(g + a) = 0.5 · 10.81 = 5.4 N, so it slips; with μ = 1.0 it holds.
    let heavy = ObjectMaterial {
        density_kg_m3: 4000.0,
        ..ObjectMaterial::default()
    };
    let slippery = Trial {
        material: ObjectMaterial {
            friction: 0.05,
            ..heavy.clone()
        },
        ..Trial::cube(0.05)
    };
    let o = run(&slippery);
    assert!((o.mass_kg - 0.5).abs() < 1e-3, "{o:#?}");
    // It was pinched before the lift (so the failure is a slip, not a miss)…
    assert!(o.both_touching_after_close, "{o:#?}");
    // …and stayed behind while the palm rose 20 cm.
    assert!(
        o.rise_after_lift_m < 0.05,
        "rose {}: {o:#?}",
        o.rise_after_lift_m
    );
    assert_not_held(&o, "μ 0.05");
    let grippy = Trial {
        material: heavy,
        ..Trial::cube(0.05)
    };
    assert_held(&run(&grippy), 0.05, "μ 1.0 control");
}

#[test]
fn closing_on_nothing_reports_missed() {
    let trial = Trial {
        empty: true,
        ..Trial::cube(0.05)
    };
    let o = run(&trial);
    assert!(!o.stopped_on_contact, "{o:#?}");
    assert!(o.closed_on_nothing_after_close, "{o:#?}");
    assert!(
        o.gap_after_close_m.abs() < 1e-3,
        "gap {}",
        o.gap_after_close_m
    );
    assert!(!o.both_touching_after_close);
    // Control: closing on a 5 cm cube does not read as missed.
    let o = run(&Trial::cube(0.05));
    assert!(!o.closed_on_nothing_after_close, "{o:#?}");
}

#[test]
fn dropped_objects_settle_on_the_table() {
    // Every procedural category, upright with a random yaw and tumbled, each in its own world,
    // plus a cube dropped from 0.5 m (no tunnelling through the 5 cm table top).
    let mut cases: Vec<(String, Mesh, DropRegion)> = Vec::new();
    for category in CATEGORIES {
        for tumble in [false, true] {
            let mesh = procedural_object(category, 0, 5).unwrap();
            let region = DropRegion {
                tumble,
                ..DropRegion::default()
            };
            cases.push((format!("{category} tumble {tumble}"), mesh, region));
        }
    }
    let high = DropRegion {
        drop_height_m: 0.5,
        tumble: true,
        ..DropRegion::default()
    };
    cases.push(("cube from 0.5 m".into(), box_mesh([0.04; 3]), high));
    for (seed, (name, mesh, region)) in cases.iter().enumerate() {
        let mut world = World::new(WorldConfig::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed as u64);
        let (h, report) = world.drop_object(name, mesh, region, &mut rng).unwrap();
        assert!(report.settled, "{name}: {report:?}");
        // It stays at rest for another second.
        for _ in 0..240 {
            world.step();
        }
        world.check_finite().unwrap();
        // On the table: the collider not sunk more than 2 mm, not floating…
        let low = lowest_hull_z(&world, h);
        assert!(
            low > TOP - 2e-3 && low < TOP + 2e-3,
            "{name}: lowest hull point at {low}"
        );
        // …and the drawn mesh within 4 mm of it (the hull drops vertices of big flat faces).
        let mesh_low = lowest_z(&world, h);
        assert!(
            mesh_low > TOP - 4e-3,
            "{name}: lowest mesh point at {mesh_low}"
        );
        let table = world.config().table.clone();
        let com = world.object_center_of_mass_m(h).unwrap();
        for k in 0..2 {
            let half = 0.5 * table.size_m[k];
            assert!(
                (com[k] - table.center_m[k]).abs() < half,
                "{name} off the table: {com:?}"
            );
        }
        let (v, w) = world.object_velocity(h).unwrap();
        let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let spin = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        assert!(
            speed < 5e-3 && spin < 0.05,
            "{name} still moving: {v:?} {w:?}"
        );
    }
}

/// Bits of every float that describes the end state.
fn pose_bits(pose: &Pose) -> Vec<u32> {
    pose.translation
        .vector
        .iter()
        .chain(pose.rotation.matrix().iter())
        .map(|v| v.to_bits())
        .collect()
}

/// Drops a procedural object with `seed`, then the arm approaches, descends (guarded), closes
/// and lifts 20 cm. Returns the end-state bits and the object's rise (m).
fn arm_episode(seed: u64, category: &str) -> (Vec<u32>, f32) {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mesh = procedural_object(category, 0, seed).unwrap();
    let (object, _) = world
        .drop_object(category, &mesh, &DropRegion::default(), &mut rng)
        .unwrap();
    let rest = world.object_pose(object).unwrap();
    let (_, hi) = mesh.bounds().unwrap();
    // The 2F-85: the heights below are chosen for its fingers.
    let config = RobotConfig {
        gripper: GripperConfig::preset(GripperModel::Robotiq2F85),
        ..RobotConfig::default()
    };
    let home = config.arm.home_rad;
    let mut robot = Robot::new(&mut world, config, &home, 0.085).unwrap();
    let arm = robot.arm().clone();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let half_pad = f64::from(robot.gripper().config().tip_from_tcp_m());
    let center = rest * Point3::new(0.0, 0.0, 0.5 * hi[2]);
    let grasp_z = f64::from(center.z).max(f64::from(TOP) + half_pad + 0.005);
    // Jaws across the object's local x axis.
    let yaw = f64::from(rest.rotation.matrix()[(1, 0)].atan2(rest.rotation.matrix()[(0, 0)]));
    let (x, y) = (f64::from(center.x), f64::from(center.y));
    let above = TopDownGrasp::new([x, y, grasp_z + 0.15], yaw);
    let q_above = ik
        .solve(&IkTarget::TopDown(above), &home)
        .unwrap()
        .joints_rad;
    let approach = JointTrajectory::point_to_point(&arm, &home, &q_above).unwrap();
    let report = robot
        .follow(&mut world, &approach, &FollowOptions::default())
        .unwrap();
    assert!(report.completed());
    let slow = LinearMove {
        speed_m_s: SPEED,
        accel_m_s2: ACCEL,
        ..LinearMove::default()
    };
    let tool_above = robot.world_from_tool();
    let mut tool_at = tool_above;
    tool_at.translation = Translation3::new(x, y, grasp_z);
    let descend = plan_linear_move(&mut ik, &robot.joints_rad(), &tool_at, &slow).unwrap();
    let guarded = FollowOptions {
        stop_on_contact: true,
    };
    robot.follow(&mut world, &descend, &guarded).unwrap();
    robot.gripper_mut().set_opening(0.0).unwrap();
    while !robot.gripper().opening_settled() {
        robot.step(&mut world).unwrap();
    }
    robot.hold(&mut world, 48).unwrap();
    let grasped: Isometry3<f64> = robot.world_from_tool();
    let mut lifted = grasped;
    lifted.translation.vector.z += 0.2;
    let lift = plan_linear_move(&mut ik, &robot.joints_rad(), &lifted, &slow).unwrap();
    robot
        .follow(&mut world, &lift, &FollowOptions::default())
        .unwrap();
    robot.hold(&mut world, 120).unwrap();
    world.check_finite().unwrap();
    let end = world.object_pose(object).unwrap();
    let mut bits = pose_bits(&end);
    for p in robot.gripper().finger_positions_in_palm_m(&world) {
        bits.extend(p.iter().map(|v| v.to_bits()));
    }
    bits.push(world.steps() as u32);
    (bits, end.translation.z - rest.translation.z)
}

#[test]
fn same_seed_and_commands_give_bit_identical_poses() {
    let (a, _) = arm_episode(3, "can");
    let (b, _) = arm_episode(3, "can");
    assert_eq!(a, b);
    // The comparison can fail: another seed ends elsewhere.
    let (c, _) = arm_episode(4, "can");
    assert_ne!(a, c);
    // And the floating-gripper script too.
    let t = Trial::cube(0.05);
    let (o1, o2) = (run(&t), run(&t));
    assert_eq!(pose_bits(&o1.final_pose), pose_bits(&o2.final_pose));
    assert_eq!(o1.steps, o2.steps);
}

#[test]
fn arm_driven_close_and_lift_holds_a_box() {
    // The arm (kinematic links along IK trajectories) carries the palm: a lying 5 × 10 × 5 cm
    // book-like box and a procedural can are lifted 20 cm.
    let (_, rise) = arm_episode(3, "can");
    assert!(rise > 0.19, "can rose {rise} m");
    let mut world = World::new(WorldConfig::default()).unwrap();
    let h = world
        .spawn_object(
            "box",
            &box_mesh([0.05, 0.1, 0.05]),
            &translation([0.1, -0.45, TOP]),
        )
        .unwrap();
    world.settle();
    let rest_z = world.object_pose(h).unwrap().translation.z;
    let config = RobotConfig {
        gripper: GripperConfig::preset(GripperModel::Robotiq2F85),
        ..RobotConfig::default()
    };
    let home = config.arm.home_rad;
    let mut robot = Robot::new(&mut world, config, &home, 0.085).unwrap();
    let arm = robot.arm().clone();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let grasp_z = f64::from(TOP) + 0.03;
    let above = TopDownGrasp::new([0.1, -0.45, grasp_z + 0.15], 0.0);
    let q = ik
        .solve(&IkTarget::TopDown(above), &home)
        .unwrap()
        .joints_rad;
    let go = JointTrajectory::point_to_point(&arm, &home, &q).unwrap();
    robot
        .follow(&mut world, &go, &FollowOptions::default())
        .unwrap();
    let mut at = robot.world_from_tool();
    at.translation.vector.z = grasp_z;
    let slow = LinearMove {
        speed_m_s: SPEED,
        accel_m_s2: ACCEL,
        ..LinearMove::default()
    };
    let down = plan_linear_move(&mut ik, &robot.joints_rad(), &at, &slow).unwrap();
    let guarded = FollowOptions {
        stop_on_contact: true,
    };
    assert!(
        robot
            .follow(&mut world, &down, &guarded)
            .unwrap()
            .completed()
    );
    assert!(robot.arm_touches(&world).is_empty());
    robot.gripper_mut().set_opening(0.0).unwrap();
    while !robot.gripper().opening_settled() {
        robot.step(&mut world).unwrap();
    }
    robot.hold(&mut world, 48).unwrap();
    let mut up = robot.world_from_tool();
    up.translation.vector.z += 0.2;
    let lift = plan_linear_move(&mut ik, &robot.joints_rad(), &up, &slow).unwrap();
    robot
        .follow(&mut world, &lift, &FollowOptions::default())
        .unwrap();
    robot.hold(&mut world, 240).unwrap();
    let rise = world.object_pose(h).unwrap().translation.z - rest_z;
    let reading = robot.gripper().grip_reading(&world, h).unwrap();
    assert!(rise > 0.195, "box rose {rise} m");
    assert!(reading.pinching(), "{reading:?}");
    assert!((reading.gap_m - 0.05).abs() < 2e-3, "{reading:?}");
}
