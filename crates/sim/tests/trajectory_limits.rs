//! Trajectory contract: every sampled state respects the joint position, speed and acceleration
//! limits, all joints start and arrive together, the last sample is exactly the goal, straight
//! tool moves stay on their line, and the same inputs give the same bits.

use lgdm_sim::robot::arm::{ArmModel, DOF, Joints};
use lgdm_sim::robot::ik::{IkConfig, IkError, IkSolver, IkTarget, TopDownGrasp, top_down_rotation};
use lgdm_sim::robot::trajectory::{JointTrajectory, LinearMove, MotionError, plan_linear_move};
use nalgebra::{Isometry3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Relative slack for floating-point rounding in the limit checks.
const SLACK: f64 = 1e-9;

fn random_joints(arm: &ArmModel, rng: &mut ChaCha8Rng) -> Joints {
    std::array::from_fn(|j| rng.random_range(arm.joint_min_rad[j]..arm.joint_max_rad[j]))
}

/// Samples `traj` every `dt` and checks positions, analytic speeds and accelerations against
/// the limits, and finite-difference speeds of `sample` against the speed limits.
fn assert_within_limits(arm: &ArmModel, traj: &JointTrajectory, what: &str) {
    let duration = traj.duration_s();
    let n = 4000;
    let dt = duration / n as f64;
    let mut prev = traj.sample(0.0);
    for i in 0..=n {
        let t = i as f64 * dt;
        let (q, v, a) = traj.state(t);
        for j in 0..DOF {
            assert!(
                q[j] >= arm.joint_min_rad[j] && q[j] <= arm.joint_max_rad[j],
                "{what}: joint {j} at {} outside limits at t = {t}",
                q[j]
            );
            let v_max = arm.max_speed_rad_s[j] * (1.0 + SLACK);
            let a_max = arm.max_accel_rad_s2[j] * (1.0 + SLACK);
            assert!(
                v[j].abs() <= v_max,
                "{what}: joint {j} speed {} at t = {t}",
                v[j]
            );
            assert!(
                a[j].abs() <= a_max,
                "{what}: joint {j} accel {} at t = {t}",
                a[j]
            );
            if i > 0 {
                let fd = (q[j] - prev[j]) / dt;
                assert!(
                    fd.abs() <= v_max * (1.0 + 1e-6) + 1e-9,
                    "{what}: joint {j} finite-difference speed {fd} at t = {t}"
                );
            }
        }
        prev = q;
    }
}

/// Trapezoid time of one joint moving `distance` from rest to rest.
fn trapezoid_time(distance: f64, v: f64, a: f64) -> f64 {
    if distance * a <= v * v {
        2.0 * (distance / a).sqrt()
    } else {
        distance / v + v / a
    }
}

#[test]
fn point_to_point_respects_limits_and_ends_exactly() {
    let arm = ArmModel::ur5e();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    for k in 0..60 {
        let q0 = random_joints(&arm, &mut rng);
        // Half long moves across the range, half short moves (triangle profiles).
        let q1 = if k % 2 == 0 {
            random_joints(&arm, &mut rng)
        } else {
            std::array::from_fn(|j| {
                (q0[j] + rng.random_range(-0.05..0.05))
                    .clamp(arm.joint_min_rad[j], arm.joint_max_rad[j])
            })
        };
        let traj = JointTrajectory::point_to_point(&arm, &q0, &q1).unwrap();
        assert_eq!(traj.sample(0.0), q0, "move {k} does not start at q0");
        assert_eq!(
            traj.sample(traj.duration_s()),
            q1,
            "move {k} does not end at q1"
        );
        assert_eq!(traj.sample(traj.duration_s() + 10.0), q1);
        assert_eq!(traj.velocity(traj.duration_s()), [0.0; DOF]);
        assert_within_limits(&arm, &traj, &format!("move {k}"));
        // Synchronised: the slowest joint sets the duration, and at every instant each joint
        // has covered the same fraction of its distance.
        let slowest = (0..DOF)
            .map(|j| {
                trapezoid_time(
                    (q1[j] - q0[j]).abs(),
                    arm.max_speed_rad_s[j],
                    arm.max_accel_rad_s2[j],
                )
            })
            .fold(0.0, f64::max);
        assert!(
            (traj.duration_s() - slowest).abs() < 1e-9 * slowest.max(1.0),
            "move {k}: duration {} vs slowest joint {slowest}",
            traj.duration_s()
        );
        let far = (0..DOF)
            .max_by(|&a, &b| (q1[a] - q0[a]).abs().total_cmp(&(q1[b] - q0[b]).abs()))
            .unwrap();
        for i in 1..20 {
            let t = traj.duration_s() * i as f64 / 20.0;
            let q = traj.sample(t);
            let fraction = (q[far] - q0[far]) / (q1[far] - q0[far]);
            for j in 0..DOF {
                let expected = q0[j] + fraction * (q1[j] - q0[j]);
                assert!(
                    (q[j] - expected).abs() < 1e-9,
                    "move {k} joint {j} off the line"
                );
            }
        }
    }
}

#[test]
fn point_to_point_rejects_bad_joints() {
    let arm = ArmModel::ur5e();
    let mut bad = arm.home_rad;
    bad[1] = f64::NAN;
    assert!(matches!(
        JointTrajectory::point_to_point(&arm, &arm.home_rad, &bad),
        Err(MotionError::Joints { which: "goal", .. })
    ));
    let mut outside = arm.home_rad;
    outside[2] = 4.0;
    assert!(matches!(
        JointTrajectory::point_to_point(&arm, &outside, &arm.home_rad),
        Err(MotionError::Joints { which: "start", .. })
    ));
    // NaN time samples the start instead of panicking.
    let traj = JointTrajectory::point_to_point(&arm, &arm.home_rad, &[0.0; DOF]).unwrap();
    assert_eq!(traj.sample(f64::NAN), arm.home_rad);
}

/// Approach from home, descend 0.20 m onto a grasp, lift back: the TCP stays on the line
/// (within 1 mm, 0.5°), never exceeds the requested tool speed, and each move ends on its goal.
#[test]
fn linear_moves_stay_on_the_line_within_limits() {
    let arm = ArmModel::ur5e();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let params = LinearMove::default();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in 0..12 {
        let grasp = TopDownGrasp::new(
            [
                rng.random_range(0.35..0.60),
                rng.random_range(-0.25..0.25),
                rng.random_range(0.02..0.10),
            ],
            rng.random_range(-PI..PI),
        );
        let above = TopDownGrasp {
            position_m: [
                grasp.position_m[0],
                grasp.position_m[1],
                grasp.position_m[2] + 0.20,
            ],
            ..grasp
        };
        let q_above = ik
            .solve(&IkTarget::TopDown(above), &arm.home_rad)
            .unwrap()
            .joints_rad;
        // The jaw yaw the solver chose above (yaw or yaw + π) is kept for the descent.
        let start_pose = arm.world_from_tool(&q_above).unwrap();
        let goal = Isometry3::from_parts(
            Translation3::from(Vector3::from(grasp.position_m)),
            start_pose.rotation,
        );
        let descend = plan_linear_move(&mut ik, &q_above, &goal, &params)
            .unwrap_or_else(|e| panic!("descent {k}: {e}"));
        let lift = plan_linear_move(&mut ik, &descend.end(), &start_pose, &params)
            .unwrap_or_else(|e| panic!("lift {k}: {e}"));
        for (name, traj, from, to) in [
            ("descend", &descend, start_pose, goal),
            ("lift", &lift, goal, start_pose),
        ] {
            let what = format!("{name} {k}");
            assert_eq!(traj.sample(0.0), traj.start());
            assert_within_limits(&arm, traj, &what);
            let end = arm
                .world_from_tool(&traj.sample(traj.duration_s()))
                .unwrap();
            assert!(
                (end.translation.vector - to.translation.vector).norm() < 1e-4,
                "{what}"
            );
            // The line takes at least length / speed.
            let length = (to.translation.vector - from.translation.vector).norm();
            assert!(traj.duration_s() >= length / params.speed_m_s, "{what}");
            let axis = (to.translation.vector - from.translation.vector) / length;
            let n = 2000;
            let dt = traj.duration_s() / n as f64;
            let mut prev = from.translation.vector;
            for i in 0..=n {
                let p = arm.world_from_tool(&traj.sample(i as f64 * dt)).unwrap();
                let d = p.translation.vector - from.translation.vector;
                let off_line = (d - axis * d.dot(&axis)).norm();
                assert!(off_line < 1e-3, "{what}: {off_line} m off the line");
                let tilt = p.rotation.angle_to(&from.rotation);
                assert!(tilt < 0.5_f64.to_radians(), "{what}: tilted {tilt} rad");
                if i > 0 {
                    let speed = (p.translation.vector - prev).norm() / dt;
                    assert!(
                        speed <= params.speed_m_s * 1.01,
                        "{what}: tool at {speed} m/s"
                    );
                }
                prev = p.translation.vector;
            }
        }
    }
}

#[test]
fn linear_move_out_of_reach_is_a_typed_error() {
    let arm = ArmModel::ur5e();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let q = arm.home_rad;
    let far = Isometry3::from_parts(Translation3::new(2.0, 0.0, 0.3), top_down_rotation(0.0));
    match plan_linear_move(&mut ik, &q, &far, &LinearMove::default()) {
        Err(MotionError::Unreachable {
            waypoint,
            waypoints,
            fraction,
            source: IkError::Unreachable { .. },
        }) => {
            assert!(
                waypoint > 1 && waypoint <= waypoints,
                "{waypoint}/{waypoints}"
            );
            assert!(fraction > 0.0 && fraction < 1.0);
        }
        other => panic!("expected Unreachable, got {other:?}"),
    }
    let nan_goal = Isometry3::from_parts(
        Translation3::new(0.4, f64::NAN, 0.3),
        top_down_rotation(0.0),
    );
    assert!(matches!(
        plan_linear_move(&mut ik, &q, &nan_goal, &LinearMove::default()),
        Err(MotionError::InvalidGoal { .. })
    ));
    let mut broken = arm.clone();
    broken.max_accel_rad_s2[3] = -1.0;
    assert!(matches!(
        JointTrajectory::point_to_point(&broken, &q, &q),
        Err(MotionError::Model(_))
    ));
    let bad = LinearMove {
        waypoint_spacing_m: f64::NAN,
        ..LinearMove::default()
    };
    let near = Isometry3::from_parts(Translation3::new(0.45, 0.0, 0.2), top_down_rotation(0.0));
    assert!(matches!(
        plan_linear_move(&mut ik, &q, &near, &bad),
        Err(MotionError::InvalidParameter {
            field: "waypoint_spacing_m",
            ..
        })
    ));
}

#[test]
fn linear_move_to_the_start_pose_is_a_hold() {
    let arm = ArmModel::ur5e();
    let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
    let q = arm.home_rad;
    let here = arm.world_from_tool(&q).unwrap();
    let traj = plan_linear_move(&mut ik, &q, &here, &LinearMove::default()).unwrap();
    assert_eq!(traj.duration_s(), 0.0);
    assert_eq!(traj.sample(0.5), q);
}

/// The bits of a planned move and its way back, as hex (the child process prints them).
fn planned_bits() -> String {
    let arm = ArmModel::ur5e();
    let run = || {
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
        let q0 = arm.home_rad;
        let goal =
            Isometry3::from_parts(Translation3::new(0.5, 0.15, 0.05), top_down_rotation(0.4));
        let line = plan_linear_move(&mut ik, &q0, &goal, &LinearMove::default()).unwrap();
        let p2p = JointTrajectory::point_to_point(&arm, &line.end(), &q0).unwrap();
        let mut bits = Vec::new();
        for traj in [&line, &p2p] {
            bits.push(traj.duration_s().to_bits());
            for i in 0..=100 {
                let q = traj.sample(traj.duration_s() * i as f64 / 100.0);
                bits.extend(q.map(f64::to_bits));
            }
        }
        bits
    };
    let bits = run();
    assert!(bits.len() > 200, "a move and its way back, sampled");
    bits.iter().map(|b| format!("{b:016x}")).collect()
}

/// The same inputs give the same bits in another process too (nothing depends on addresses,
/// hash seeds or the time): the test runs itself as a child, which prints its bits.
#[test]
fn same_inputs_give_same_bits() {
    const CHILD: &str = "LGDM_TRAJECTORY_BITS_CHILD";
    let here = planned_bits();
    if std::env::var_os(CHILD).is_some() {
        println!("bits={here}");
        return;
    }
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "same_inputs_give_same_bits",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, "1")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let child = text
        .lines()
        .find_map(|l| l.split_once("bits=").map(|(_, b)| b.trim()))
        .expect("the child printed its bits");
    assert_eq!(child, here);
}
