//! IK contract: for reachable top-down poses over the tabletop, FK(IK(T)) = T within 1 mm and
//! 0.5° with every joint inside its limits; unreachable and invalid targets are typed errors,
//! never a pose; the same inputs give the same bits.
//!
//! Two sets of reachable poses, ≥ 200 each, both seeded RNGs:
//! - *joint-space*: random in-limit joints constrained to the top-down family of a UR arm
//!   (joints 2 + 3 + 4 = −π/2, joint 5 = −π/2), so each pose is reachable by construction,
//!   kept when the TCP lies in the tabletop band in front of the base;
//! - *box*: positions and yaws drawn uniformly in a box in front of the base. These are only
//!   claimed reachable — the test asserts that every one solves, so the claim is checked here.

use lgdm_sim::robot::arm::{ArmModel, DOF, Joints};
use lgdm_sim::robot::ik::{IkConfig, IkError, IkSolver, IkTarget, TopDownGrasp, top_down_rotation};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;
use std::time::Instant;

const POSITION_TOL_M: f64 = 1e-3;
const ORIENTATION_TOL_RAD: f64 = 0.5 * PI / 180.0;

/// The arm on a table: base 0.785 m up (the reference table top), at (−0.5, 0.1), turned 0.25 rad.
fn table_arm() -> ArmModel {
    ArmModel::ur5e().with_world_from_base(&Isometry3::new(
        Vector3::new(-0.5, 0.1, 0.785),
        Vector3::new(0.0, 0.0, 0.25),
    ))
}

fn base_to_world(arm: &ArmModel, p_base: [f64; 3]) -> [f64; 3] {
    let p = arm.world_from_base.to_isometry() * Point3::from(p_base);
    [p.x, p.y, p.z]
}

fn assert_reaches(arm: &ArmModel, q: &Joints, target: &Isometry3<f64>, what: &str) {
    arm.check_joints(q)
        .unwrap_or_else(|e| panic!("{what}: solution outside limits: {e}"));
    let reached = arm.world_from_tool(q).unwrap();
    let dp = (reached.translation.vector - target.translation.vector).norm();
    let dr = reached.rotation.angle_to(&target.rotation);
    assert!(dp < POSITION_TOL_M, "{what}: position error {dp} m");
    assert!(
        dr < ORIENTATION_TOL_RAD,
        "{what}: orientation error {dr} rad"
    );
}

/// The grasp's tool pose, or the one at yaw + π if the solver took the jaw-symmetric twin.
fn grasp_pose_reached(arm: &ArmModel, q: &Joints, grasp: &TopDownGrasp) -> Isometry3<f64> {
    let reached = arm.world_from_tool(q).unwrap();
    let [x, y, z] = grasp.position_m;
    let a = top_down_rotation(grasp.yaw_rad);
    let b = top_down_rotation(grasp.yaw_rad + PI);
    let rotation = if reached.rotation.angle_to(&a) <= reached.rotation.angle_to(&b) {
        a
    } else {
        b
    };
    Isometry3::from_parts(Translation3::new(x, y, z), rotation)
}

/// The tabletop band in the base frame: 2–45 cm above the base plane, 25–75 cm from the base
/// axis, in front (x > 0.15 m).
fn in_tabletop_band(p: &Vector3<f64>) -> bool {
    let r = (p.x * p.x + p.y * p.y).sqrt();
    (0.02..=0.45).contains(&p.z) && (0.25..=0.75).contains(&r) && p.x > 0.15
}

#[test]
fn fk_of_ik_matches_joint_space_top_down_poses() {
    let arm = table_arm();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let base_from_world = arm.world_from_base.to_isometry().inverse();
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let mut targets = Vec::new();
    let mut draws = 0;
    while targets.len() < 250 {
        draws += 1;
        assert!(
            draws < 2_000_000,
            "generator found only {} poses",
            targets.len()
        );
        let q2 = rng.random_range(-PI..0.0);
        let q3 = rng.random_range(-PI..PI);
        let mut q4 = -PI / 2.0 - q2 - q3;
        if q4 < -2.0 * PI {
            q4 += 2.0 * PI;
        }
        let q: Joints = [
            rng.random_range(-2.0 * PI..2.0 * PI),
            q2,
            q3,
            q4,
            -PI / 2.0,
            rng.random_range(-2.0 * PI..2.0 * PI),
        ];
        arm.check_joints(&q).unwrap();
        let pose = arm.world_from_tool(&q).unwrap();
        let tool_z = pose.rotation * Vector3::z();
        assert!((tool_z.z + 1.0).abs() < 1e-9, "family is not top-down");
        if in_tabletop_band(&(base_from_world * pose.translation.vector)) {
            targets.push(pose);
        }
    }
    // Seed each solve from the previous solution, as the sim does (current joints).
    let mut seed = arm.home_rad;
    let start = Instant::now();
    let mut iterations = 0;
    for (i, target) in targets.iter().enumerate() {
        let solution = ik
            .solve(&IkTarget::Pose(*target), &seed)
            .unwrap_or_else(|e| panic!("pose {i}: {e}"));
        assert_reaches(&arm, &solution.joints_rad, target, &format!("pose {i}"));
        iterations += solution.iterations;
        seed = solution.joints_rad;
    }
    let elapsed = start.elapsed();
    println!(
        "joint-space set: {} poses, {:.1} µs per solve, {:.1} QP iterations per solve",
        targets.len(),
        elapsed.as_secs_f64() * 1e6 / targets.len() as f64,
        iterations as f64 / targets.len() as f64,
    );
}

#[test]
fn fk_of_ik_matches_box_sampled_top_down_grasps() {
    let arm = table_arm();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let n = 300;
    let start = Instant::now();
    let mut iterations = 0;
    for i in 0..n {
        // Box in the base frame: 0.30–0.65 m ahead, ±0.30 m across, 0.02–0.40 m above the table.
        let p_base = [
            rng.random_range(0.30..0.65),
            rng.random_range(-0.30..0.30),
            rng.random_range(0.02..0.40),
        ];
        let grasp = TopDownGrasp::new(base_to_world(&arm, p_base), rng.random_range(-PI..PI));
        // Seeded from home: the sim's first move of an attempt.
        let solution = ik
            .solve(&IkTarget::TopDown(grasp), &arm.home_rad)
            .unwrap_or_else(|e| panic!("grasp {i} at {p_base:?}: {e}"));
        let target = grasp_pose_reached(&arm, &solution.joints_rad, &grasp);
        assert_reaches(&arm, &solution.joints_rad, &target, &format!("grasp {i}"));
        let tool_z = arm.world_from_tool(&solution.joints_rad).unwrap().rotation * Vector3::z();
        assert!(
            tool_z.z < -(0.5_f64.to_radians().cos()),
            "grasp {i} not top-down"
        );
        iterations += solution.iterations;
    }
    let elapsed = start.elapsed();
    println!(
        "box set: {n} grasps (both jaw yaws each), {:.1} µs per solve, {:.1} QP iterations per solve",
        elapsed.as_secs_f64() * 1e6 / n as f64,
        iterations as f64 / n as f64,
    );
}

#[test]
fn jaw_symmetric_grasp_takes_the_yaw_nearer_the_seed() {
    let arm = ArmModel::ur5e();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let home = arm.home_rad;
    // Home has jaw yaw 0; asking for yaw π must turn the wrist by ~0, not by π.
    let grasp = TopDownGrasp::new([0.45, 0.0, 0.2], PI);
    let q = ik
        .solve(&IkTarget::TopDown(grasp), &home)
        .unwrap()
        .joints_rad;
    assert!(
        (q[5] - home[5]).abs() < 0.1,
        "wrist turned {}",
        q[5] - home[5]
    );
    let strict = TopDownGrasp {
        jaw_symmetric: false,
        ..grasp
    };
    let q = ik
        .solve(&IkTarget::TopDown(strict), &home)
        .unwrap()
        .joints_rad;
    assert!(
        (q[5] - home[5]).abs() > 3.0,
        "wrist turned {}",
        q[5] - home[5]
    );
    assert_reaches(&arm, &q, &strict.world_from_tool(), "strict yaw");
}

#[test]
fn unreachable_pose_is_a_typed_error() {
    let arm = table_arm();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let far = base_to_world(&arm, [2.0, 0.0, 0.1]);
    let result = ik.solve(
        &IkTarget::TopDown(TopDownGrasp::new(far, 0.0)),
        &arm.home_rad,
    );
    match result {
        Err(IkError::Unreachable {
            position_error_m,
            orientation_error_rad,
        }) => {
            assert!(position_error_m > 0.9, "{position_error_m}");
            assert!(orientation_error_rad.is_finite());
        }
        other => panic!("expected Unreachable, got {other:?}"),
    }
    // A full pose 2 m above the base.
    let up = Isometry3::from_parts(
        Translation3::from(Vector3::from(base_to_world(&arm, [0.0, 0.0, 2.0]))),
        UnitQuaternion::identity(),
    );
    assert!(matches!(
        ik.solve(&IkTarget::Pose(up), &arm.home_rad),
        Err(IkError::Unreachable { .. })
    ));
}

#[test]
fn target_needing_a_joint_beyond_its_limit_is_a_joint_limits_error() {
    // The base may turn only ±0.5 rad around home (which faces +x): a grasp behind the base is
    // within reach of the arm but not of these limits.
    let mut arm = ArmModel::ur5e();
    arm.joint_min_rad[0] = arm.home_rad[0] - 0.5;
    arm.joint_max_rad[0] = arm.home_rad[0] + 0.5;
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let behind = TopDownGrasp::new([-0.45, 0.0, 0.2], 0.0);
    match ik.solve(&IkTarget::TopDown(behind), &arm.home_rad) {
        Err(IkError::JointLimits { joints, .. }) => assert_eq!(joints, vec![0]),
        other => panic!("expected JointLimits, got {other:?}"),
    }
    // The same grasp in front still solves.
    let front = TopDownGrasp::new([0.45, 0.0, 0.2], 0.0);
    assert!(ik.solve(&IkTarget::TopDown(front), &arm.home_rad).is_ok());
}

#[test]
fn nan_inputs_are_errors() {
    let arm = ArmModel::ur5e();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let home = arm.home_rad;
    let nan_position = TopDownGrasp::new([0.4, f64::NAN, 0.1], 0.0);
    assert!(matches!(
        ik.solve(&IkTarget::TopDown(nan_position), &home),
        Err(IkError::InvalidTarget { .. })
    ));
    let nan_yaw = TopDownGrasp::new([0.4, 0.0, 0.1], f64::NAN);
    assert!(matches!(
        ik.solve(&IkTarget::TopDown(nan_yaw), &home),
        Err(IkError::InvalidTarget { .. })
    ));
    let nan_pose = Isometry3::from_parts(
        Translation3::new(0.4, 0.0, f64::INFINITY),
        UnitQuaternion::identity(),
    );
    assert!(matches!(
        ik.solve(&IkTarget::Pose(nan_pose), &home),
        Err(IkError::InvalidTarget { .. })
    ));
    let mut nan_seed = home;
    nan_seed[4] = f64::NAN;
    let ok_target = IkTarget::TopDown(TopDownGrasp::new([0.4, 0.0, 0.1], 0.0));
    assert!(matches!(
        ik.solve(&ok_target, &nan_seed),
        Err(IkError::Seed(_))
    ));
    // The solver still works after the errors.
    assert!(ik.solve(&ok_target, &home).is_ok());
}

/// Every link origin of the UR5e (and the UR5 CB3) at q = 0, worked out by hand from the DH
/// table: with all θ = 0, `T_i = Tz(d_i)·Tx(a_i)·Rx(α_i)`, so frame 1 sits at (0, 0, d1) with
/// z₁ = −y; frames 2 and 3 move along x by a2 and a3; frame 4 moves by d4 along z₃ = −y and its
/// z₄ = −z; frame 5 moves by d5 down; z₅ = −y, so the flange is at (a2 + a3, −(d4 + d6), d1 − d5)
/// with its z along −y and x along +x, and the TCP L further along −y.
#[test]
fn fk_at_zero_joints_matches_the_dh_table() {
    for (arm, d1, a2, a3, d4, d5, d6) in [
        (
            ArmModel::ur5e(),
            0.1625,
            -0.425,
            -0.3922,
            0.1333,
            0.0997,
            0.0996,
        ),
        (
            ArmModel::ur5_cb3(),
            0.089159,
            -0.425,
            -0.39225,
            0.10915,
            0.09465,
            0.0823,
        ),
    ] {
        let tool_m = 0.15;
        let pose = arm.forward(&[0.0; DOF]).unwrap();
        let expected_origins = [
            [0.0, 0.0, d1],
            [a2, 0.0, d1],
            [a2 + a3, 0.0, d1],
            [a2 + a3, -d4, d1],
            [a2 + a3, -d4, d1 - d5],
            [a2 + a3, -(d4 + d6), d1 - d5],
        ];
        for (i, e) in expected_origins.iter().enumerate() {
            let o = pose.world_from_link[i].translation.vector;
            assert!(
                (o - Vector3::from(*e)).norm() < 1e-12,
                "{:?} link {} at {o:?}, expected {e:?}",
                arm.kind,
                i + 1
            );
        }
        let tool = pose.world_from_tool;
        let expected_tool = Vector3::new(a2 + a3, -(d4 + d6 + tool_m), d1 - d5);
        assert!((tool.translation.vector - expected_tool).norm() < 1e-12);
        assert!((tool.rotation * Vector3::z() - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        assert!((tool.rotation * Vector3::x() - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
    }
    // UR5e numbers, spelled out: (−0.8172, −0.3829, 0.0628) with the 0.15 m tool.
    let tool = ArmModel::ur5e().world_from_tool(&[0.0; DOF]).unwrap();
    let t = tool.translation.vector;
    assert!(
        (t - Vector3::new(-0.8172, -0.3829, 0.0628)).norm() < 1e-12,
        "{t:?}"
    );
}

#[test]
fn home_posture_is_top_down_in_front_of_the_base() {
    let arm = ArmModel::ur5e();
    let tool = arm.world_from_tool(&arm.home_rad).unwrap();
    let t = tool.translation.vector;
    assert!(
        (t - Vector3::new(0.45, 0.0, 0.30)).norm() < 5e-3,
        "home TCP at {t:?}"
    );
    assert!((tool.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    // Jaw yaw 0: tool x along +x.
    assert!((tool.rotation * Vector3::x() - Vector3::x()).norm() < 1e-9);
    // Elbow up: the elbow (frame 2's origin) above the shoulder (frame 1's).
    let pose = arm.forward(&arm.home_rad).unwrap();
    assert!(pose.world_from_link[1].translation.z > pose.world_from_link[0].translation.z);
}

#[test]
fn same_inputs_give_same_bits() {
    let arm = table_arm();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let grasps: Vec<TopDownGrasp> = (0..40)
        .map(|_| {
            let p = [
                rng.random_range(0.30..0.65),
                rng.random_range(-0.30..0.30),
                rng.random_range(0.02..0.40),
            ];
            TopDownGrasp::new(base_to_world(&arm, p), rng.random_range(-PI..PI))
        })
        .collect();
    let run = |order: &[usize]| {
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
        let mut out = vec![[0u64; DOF]; grasps.len()];
        for &i in order {
            let q = ik
                .solve(&IkTarget::TopDown(grasps[i]), &arm.home_rad)
                .unwrap()
                .joints_rad;
            out[i] = q.map(f64::to_bits);
        }
        out
    };
    let forward: Vec<usize> = (0..grasps.len()).collect();
    let backward: Vec<usize> = forward.iter().rev().copied().collect();
    let a = run(&forward);
    assert_eq!(a, run(&forward), "fresh solvers differ");
    assert_eq!(a, run(&backward), "a reused solver depends on its history");
}
