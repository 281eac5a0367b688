//! Time-parameterised joint trajectories within the arm's speed and acceleration limits.
//!
//! A [`JointTrajectory`] is a joint-space path `q(s)` — a C¹ piecewise cubic through waypoints,
//! monotone per joint between waypoints so it never leaves their range (hence never the joint
//! limits) — timed by one trapezoidal speed profile `s(t)` (accelerate, cruise, decelerate; a
//! triangle for short moves). The profile's peak speed and acceleration are the largest that
//! keep every joint within its limits over the whole path, so all joints start and arrive
//! together:
//! - [`JointTrajectory::point_to_point`]: a straight line in joint space from `q0` to `q1`
//!   (per joint a trapezoid, scaled to the slowest joint).
//! - [`plan_linear_move`]: a straight line of the tool in the world (approach, descend, lift):
//!   IK waypoints every few millimetres, each seeded from the previous one and checked for
//!   jumps, timed at a requested tool speed (slower where a joint limit binds).
//!
//! ```
//! use lgdm_sim::robot::arm::ArmModel;
//! use lgdm_sim::robot::trajectory::JointTrajectory;
//! let arm = ArmModel::ur5e();
//! let q0 = arm.home_rad;
//! let mut q1 = q0;
//! q1[0] += 0.5;
//! let traj = JointTrajectory::point_to_point(&arm, &q0, &q1).unwrap();
//! assert!(traj.duration_s() > 0.0);
//! assert_eq!(traj.sample(traj.duration_s()), q1);
//! ```

use crate::robot::arm::{ArmModel, ArmModelError, DOF, Joints, JointsError};
use crate::robot::ik::{IkError, IkSolver, check_pose};
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

/// A trapezoidal speed profile over a path of `length`, starting and ending at rest.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Trapezoid {
    length: f64,
    accel: f64,
    peak_speed: f64,
    t_accel: f64,
    t_cruise: f64,
}

impl Trapezoid {
    /// The fastest profile with speed ≤ `max_speed` and |acceleration| ≤ `max_accel`.
    fn new(length: f64, max_speed: f64, max_accel: f64) -> Self {
        if length <= 0.0 || max_speed <= 0.0 || max_accel <= 0.0 {
            return Self {
                length: length.max(0.0),
                accel: max_accel.max(0.0),
                peak_speed: 0.0,
                t_accel: 0.0,
                t_cruise: 0.0,
            };
        }
        if length * max_accel <= max_speed * max_speed {
            // Triangle: never reaches the speed limit.
            let peak_speed = (length * max_accel).sqrt();
            Self {
                length,
                accel: max_accel,
                peak_speed,
                t_accel: peak_speed / max_accel,
                t_cruise: 0.0,
            }
        } else {
            let t_accel = max_speed / max_accel;
            Self {
                length,
                accel: max_accel,
                peak_speed: max_speed,
                t_accel,
                t_cruise: (length - max_speed * t_accel) / max_speed,
            }
        }
    }

    fn duration(&self) -> f64 {
        2.0 * self.t_accel + self.t_cruise
    }

    /// Path position, speed and acceleration at time `t` (clamped to the profile).
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let total = self.duration();
        if total <= 0.0 || t >= total {
            return (self.length, 0.0, 0.0);
        }
        let t = t.max(0.0);
        let (a, v, ta) = (self.accel, self.peak_speed, self.t_accel);
        if t < ta {
            (0.5 * a * t * t, a * t, a)
        } else if t < ta + self.t_cruise {
            (0.5 * a * ta * ta + v * (t - ta), v, 0.0)
        } else {
            let r = total - t;
            ((self.length - 0.5 * a * r * r).min(self.length), a * r, -a)
        }
    }
}

/// A joint trajectory: a C¹ path through waypoints timed by a trapezoidal profile.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    /// Path parameter of each waypoint, increasing from 0.
    knots_s: Vec<f64>,
    /// Waypoints (rad).
    waypoints: Vec<Joints>,
    /// dq/ds at each waypoint.
    tangents: Vec<Joints>,
    profile: Trapezoid,
}

/// Why a trajectory could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// A start, goal or waypoint joint vector is NaN or outside the limits.
    #[error("{which} joints: {source}")]
    Joints {
        /// `start`, `goal` or `waypoint`.
        which: &'static str,
        /// What is wrong.
        source: JointsError,
    },
    /// A parameter is not a positive finite number.
    #[error("motion parameter {field} = {value} must be positive and finite")]
    InvalidParameter {
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// The goal pose has a NaN or infinite component or a non-unit rotation.
    #[error("linear move goal: {reason}")]
    InvalidGoal {
        /// What is wrong.
        reason: &'static str,
    },
    /// The arm model is invalid.
    #[error(transparent)]
    Model(#[from] ArmModelError),
    /// IK failed at a waypoint of a straight-line move.
    #[error(
        "waypoint {waypoint} of {waypoints} ({fraction:.3} of the way) has no IK solution: {source}"
    )]
    Unreachable {
        /// Index of the failing waypoint (1 = first after the start).
        waypoint: usize,
        /// Number of waypoints after the start.
        waypoints: usize,
        /// How far along the line it lies (0..1).
        fraction: f64,
        /// The IK error.
        source: IkError,
    },
    /// Consecutive waypoints are too far apart in joint space (the IK switched branch or the
    /// line passes a singularity).
    #[error("waypoint {waypoint}: joint {joint} jumps {jump_rad} rad (limit {limit_rad})")]
    JointJump {
        /// Index of the waypoint.
        waypoint: usize,
        /// Joint that jumps.
        joint: usize,
        /// Size of the jump (rad).
        jump_rad: f64,
        /// The allowed jump (rad).
        limit_rad: f64,
    },
}

impl JointTrajectory {
    /// The fastest straight joint-space move from `q0` to `q1` with every joint within its
    /// speed and acceleration limits; all joints start and stop together.
    pub fn point_to_point(model: &ArmModel, q0: &Joints, q1: &Joints) -> Result<Self, MotionError> {
        model.validate()?;
        model
            .check_joints(q0)
            .map_err(|source| MotionError::Joints {
                which: "start",
                source,
            })?;
        model
            .check_joints(q1)
            .map_err(|source| MotionError::Joints {
                which: "goal",
                source,
            })?;
        Ok(Self::through(
            model,
            vec![*q0, *q1],
            vec![0.0, 1.0],
            f64::INFINITY,
            f64::INFINITY,
        ))
    }

    /// A trajectory that stays at `q` (duration 0).
    pub fn hold(model: &ArmModel, q: &Joints) -> Result<Self, MotionError> {
        model.validate()?;
        model
            .check_joints(q)
            .map_err(|source| MotionError::Joints {
                which: "start",
                source,
            })?;
        Ok(Self::through(
            model,
            vec![*q],
            vec![0.0],
            f64::INFINITY,
            f64::INFINITY,
        ))
    }

    /// A path through `waypoints` at path parameters `knots_s` (strictly increasing from 0),
    /// timed with path speed ≤ `max_path_speed` and path acceleration ≤ `max_path_accel`,
    /// further limited so every joint stays within its speed and acceleration limits. Callers
    /// pass at least one waypoint and one knot per waypoint.
    fn through(
        model: &ArmModel,
        waypoints: Vec<Joints>,
        knots_s: Vec<f64>,
        max_path_speed: f64,
        max_path_accel: f64,
    ) -> Self {
        debug_assert!(!waypoints.is_empty() && waypoints.len() == knots_s.len());
        let tangents = monotone_tangents(&waypoints, &knots_s);
        let mut traj = Self {
            knots_s,
            waypoints,
            tangents,
            profile: Trapezoid::new(0.0, 0.0, 0.0),
        };
        let length = traj.knots_s.last().copied().unwrap_or(0.0);
        let (d1, d2) = traj.derivative_bounds();
        // Path speed V: |q'|·V ≤ v_max and |q''|·V² ≤ a_max / 2; then path acceleration A:
        // |q''|·V² + |q'|·A ≤ a_max.
        let mut speed = max_path_speed;
        for j in 0..DOF {
            if d1[j] > 0.0 {
                speed = speed.min(model.max_speed_rad_s[j] / d1[j]);
            }
            if d2[j] > 0.0 {
                speed = speed.min((0.5 * model.max_accel_rad_s2[j] / d2[j]).sqrt());
            }
        }
        let mut accel = max_path_accel;
        for j in 0..DOF {
            if d1[j] > 0.0 {
                accel = accel.min((model.max_accel_rad_s2[j] - d2[j] * speed * speed) / d1[j]);
            }
        }
        if !speed.is_finite() || !accel.is_finite() {
            // No joint moves: a zero-length path.
            speed = 0.0;
            accel = 0.0;
        }
        traj.profile = Trapezoid::new(length, speed, accel);
        traj
    }

    /// Total time (s).
    pub fn duration_s(&self) -> f64 {
        self.profile.duration()
    }

    /// The first waypoint (rad).
    pub fn start(&self) -> Joints {
        self.waypoints[0]
    }

    /// The last waypoint (rad): `sample(t)` returns exactly this for `t ≥ duration_s()`.
    pub fn end(&self) -> Joints {
        self.waypoints[self.waypoints.len() - 1]
    }

    /// The waypoints the path passes through (rad).
    pub fn waypoints(&self) -> &[Joints] {
        &self.waypoints
    }

    /// Joint positions at time `t_s` (clamped to `[0, duration]`; NaN gives the start).
    pub fn sample(&self, t_s: f64) -> Joints {
        self.state(t_s).0
    }

    /// Joint speeds at time `t_s` (rad/s).
    pub fn velocity(&self, t_s: f64) -> Joints {
        self.state(t_s).1
    }

    /// Joint positions (rad), speeds (rad/s) and accelerations (rad/s²) at time `t_s`.
    pub fn state(&self, t_s: f64) -> (Joints, Joints, Joints) {
        let t = if t_s.is_nan() { 0.0 } else { t_s };
        if t >= self.duration_s() {
            return (self.end(), [0.0; DOF], [0.0; DOF]);
        }
        let (s, s_dot, s_ddot) = self.profile.eval(t);
        let (q, dq_ds, d2q_ds2) = self.path(s);
        let v = std::array::from_fn(|j| dq_ds[j] * s_dot);
        let a = std::array::from_fn(|j| d2q_ds2[j] * s_dot * s_dot + dq_ds[j] * s_ddot);
        (q, v, a)
    }

    /// Path position and its first two derivatives with respect to `s`.
    fn path(&self, s: f64) -> (Joints, Joints, Joints) {
        let n = self.knots_s.len();
        if n == 1 {
            return (self.waypoints[0], [0.0; DOF], [0.0; DOF]);
        }
        // Segment k covers [knots_s[k], knots_s[k + 1]].
        let k = self
            .knots_s
            .partition_point(|&x| x <= s)
            .saturating_sub(1)
            .min(n - 2);
        let h = self.knots_s[k + 1] - self.knots_s[k];
        let u = ((s - self.knots_s[k]) / h).clamp(0.0, 1.0);
        let (p0, p1) = (&self.waypoints[k], &self.waypoints[k + 1]);
        let (m0, m1) = (&self.tangents[k], &self.tangents[k + 1]);
        let (u2, u3) = (u * u, u * u * u);
        let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
        let h10 = u3 - 2.0 * u2 + u;
        let h01 = -2.0 * u3 + 3.0 * u2;
        let h11 = u3 - u2;
        let d00 = 6.0 * u2 - 6.0 * u;
        let d10 = 3.0 * u2 - 4.0 * u + 1.0;
        let d01 = -6.0 * u2 + 6.0 * u;
        let d11 = 3.0 * u2 - 2.0 * u;
        let dd00 = 12.0 * u - 6.0;
        let dd10 = 6.0 * u - 4.0;
        let dd01 = -12.0 * u + 6.0;
        let dd11 = 6.0 * u - 2.0;
        let q =
            std::array::from_fn(|j| h00 * p0[j] + h10 * h * m0[j] + h01 * p1[j] + h11 * h * m1[j]);
        let dq = std::array::from_fn(|j| {
            (d00 * p0[j] + d10 * h * m0[j] + d01 * p1[j] + d11 * h * m1[j]) / h
        });
        let ddq = std::array::from_fn(|j| {
            (dd00 * p0[j] + dd10 * h * m0[j] + dd01 * p1[j] + dd11 * h * m1[j]) / (h * h)
        });
        (q, dq, ddq)
    }

    /// Per joint, the largest |dq/ds| and |d²q/ds²| over the path (exact for the cubic pieces).
    fn derivative_bounds(&self) -> (Joints, Joints) {
        let mut d1 = [0.0_f64; DOF];
        let mut d2 = [0.0_f64; DOF];
        for k in 0..self.knots_s.len().saturating_sub(1) {
            let h = self.knots_s[k + 1] - self.knots_s[k];
            for j in 0..DOF {
                let (p0, p1) = (self.waypoints[k][j], self.waypoints[k + 1][j]);
                let (m0, m1) = (self.tangents[k][j] * h, self.tangents[k + 1][j] * h);
                // dq/ds · h = a u² + b u + c.
                let a = 6.0 * p0 + 3.0 * m0 - 6.0 * p1 + 3.0 * m1;
                let b = -6.0 * p0 - 4.0 * m0 + 6.0 * p1 - 2.0 * m1;
                let c = m0;
                let mut m = c.abs().max((a + b + c).abs());
                if a != 0.0 {
                    let u = -b / (2.0 * a);
                    if u > 0.0 && u < 1.0 {
                        m = m.max((a * u * u + b * u + c).abs());
                    }
                }
                d1[j] = d1[j].max(m / h);
                // d²q/ds² · h² is linear in u: check both ends.
                let s0 = -6.0 * p0 - 4.0 * m0 + 6.0 * p1 - 2.0 * m1;
                let s1 = 6.0 * p0 + 2.0 * m0 - 6.0 * p1 + 4.0 * m1;
                d2[j] = d2[j].max(s0.abs().max(s1.abs()) / (h * h));
            }
        }
        (d1, d2)
    }
}

/// Tangents that keep each joint monotone between waypoints (Fritsch–Butland): zero where the
/// joint turns around, the harmonic mean of the neighbouring slopes elsewhere, one-sided at the
/// ends.
fn monotone_tangents(waypoints: &[Joints], knots_s: &[f64]) -> Vec<Joints> {
    let n = waypoints.len();
    if n < 2 {
        return vec![[0.0; DOF]; n];
    }
    let slope = |k: usize, j: usize| {
        (waypoints[k + 1][j] - waypoints[k][j]) / (knots_s[k + 1] - knots_s[k])
    };
    (0..n)
        .map(|k| {
            std::array::from_fn(|j| {
                if k == 0 {
                    slope(0, j)
                } else if k == n - 1 {
                    slope(n - 2, j)
                } else {
                    let (d0, d1) = (slope(k - 1, j), slope(k, j));
                    if d0 * d1 <= 0.0 {
                        0.0
                    } else {
                        2.0 * d0 * d1 / (d0 + d1)
                    }
                }
            })
        })
        .collect()
}

/// Parameters of a straight-line tool move. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinearMove {
    /// Cruise speed of the tool along the line (m/s; default 0.15).
    pub speed_m_s: f64,
    /// Acceleration of the tool along the line (m/s²; default 0.5).
    pub accel_m_s2: f64,
    /// Spacing of the IK waypoints along the line (m; default 0.005).
    pub waypoint_spacing_m: f64,
    /// A rotation of the tool counts as this many metres per radian of path, for spacing and
    /// timing (m/rad; default 0.1).
    pub rotation_length_m_per_rad: f64,
    /// Largest joint change allowed between consecutive waypoints (rad; default 0.2).
    pub max_joint_jump_rad: f64,
}

impl Default for LinearMove {
    fn default() -> Self {
        Self {
            speed_m_s: 0.15,
            accel_m_s2: 0.5,
            waypoint_spacing_m: 0.005,
            rotation_length_m_per_rad: 0.1,
            max_joint_jump_rad: 0.2,
        }
    }
}

impl LinearMove {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), MotionError> {
        for (field, value) in [
            ("speed_m_s", self.speed_m_s),
            ("accel_m_s2", self.accel_m_s2),
            ("waypoint_spacing_m", self.waypoint_spacing_m),
            ("rotation_length_m_per_rad", self.rotation_length_m_per_rad),
            ("max_joint_jump_rad", self.max_joint_jump_rad),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(MotionError::InvalidParameter { field, value });
            }
        }
        Ok(())
    }
}

/// A linear move shorter than this (m, rotation included) is a hold.
const MIN_LENGTH_M: f64 = 1e-9;

/// Most waypoints a linear move may have (a 10 m line at the default spacing).
const MAX_WAYPOINTS: usize = 2000;

/// A straight-line tool move from the pose at `q_start` to `world_from_tool_goal` (position
/// interpolated linearly, orientation by slerp), as a timed joint trajectory. Every waypoint is
/// solved by IK seeded from the previous one, lies within the joint limits and is within
/// `max_joint_jump_rad` of its predecessor; the tool cruises at `speed_m_s`, slower if a joint's
/// speed or acceleration limit would otherwise be exceeded.
pub fn plan_linear_move(
    ik: &mut IkSolver,
    q_start: &Joints,
    world_from_tool_goal: &Isometry3<f64>,
    params: &LinearMove,
) -> Result<JointTrajectory, MotionError> {
    params.validate()?;
    let model = ik.model().clone();
    model
        .check_joints(q_start)
        .map_err(|source| MotionError::Joints {
            which: "start",
            source,
        })?;
    if let Err(IkError::InvalidTarget { reason }) = check_pose(world_from_tool_goal) {
        return Err(MotionError::InvalidGoal { reason });
    }
    let start = model.forward_unchecked(q_start).world_from_tool;
    let distance_m = (world_from_tool_goal.translation.vector - start.translation.vector).norm();
    let angle_rad = start.rotation.angle_to(&world_from_tool_goal.rotation);
    let length = distance_m.max(angle_rad * params.rotation_length_m_per_rad);
    if length < MIN_LENGTH_M {
        // Start and goal coincide (to rounding): stay put.
        return JointTrajectory::hold(&model, q_start);
    }
    let steps = (length / params.waypoint_spacing_m).ceil();
    if steps > MAX_WAYPOINTS as f64 {
        return Err(MotionError::InvalidParameter {
            field: "waypoint_spacing_m",
            value: params.waypoint_spacing_m,
        });
    }
    let steps = (steps as usize).max(1);
    let mut waypoints = Vec::with_capacity(steps + 1);
    let mut knots_s = Vec::with_capacity(steps + 1);
    waypoints.push(*q_start);
    knots_s.push(0.0);
    let mut q = *q_start;
    for i in 1..=steps {
        let fraction = i as f64 / steps as f64;
        let pose = if i == steps {
            *world_from_tool_goal
        } else {
            // try_slerp only declines when the two rotations (nearly) coincide.
            let rotation = start
                .rotation
                .try_slerp(&world_from_tool_goal.rotation, fraction, 1e-12)
                .unwrap_or(start.rotation);
            let translation = start
                .translation
                .vector
                .lerp(&world_from_tool_goal.translation.vector, fraction);
            Isometry3::from_parts(translation.into(), rotation)
        };
        let solution = ik
            .solve_local(&pose, &q)
            .map_err(|source| MotionError::Unreachable {
                waypoint: i,
                waypoints: steps,
                fraction,
                source,
            })?;
        let next = solution.joints_rad;
        for j in 0..DOF {
            let jump_rad = (next[j] - q[j]).abs();
            if jump_rad > params.max_joint_jump_rad {
                return Err(MotionError::JointJump {
                    waypoint: i,
                    joint: j,
                    jump_rad,
                    limit_rad: params.max_joint_jump_rad,
                });
            }
        }
        q = next;
        waypoints.push(q);
        knots_s.push(length * fraction);
    }
    Ok(JointTrajectory::through(
        &model,
        waypoints,
        knots_s,
        params.speed_m_s,
        params.accel_m_s2,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_length_and_respects_limits() {
        for (len, v, a) in [(1.0, 0.5, 1.0), (0.01, 0.5, 1.0), (2.0, 3.0, 0.7)] {
            let p = Trapezoid::new(len, v, a);
            let (s_end, v_end, _) = p.eval(p.duration());
            assert_eq!(s_end, len);
            assert_eq!(v_end, 0.0);
            let n = 1000;
            let mut prev = 0.0;
            for i in 0..=n {
                let t = p.duration() * i as f64 / n as f64;
                let (s, sd, sdd) = p.eval(t);
                assert!(s >= prev - 1e-15 && s <= len);
                assert!(sd <= v * (1.0 + 1e-12) && sd >= 0.0);
                assert!(sdd.abs() <= a * (1.0 + 1e-12));
                prev = s;
            }
            // Just before the end the profile is continuous.
            let (s, _, _) = p.eval(p.duration() * (1.0 - 1e-9));
            assert!((s - len).abs() < 1e-9);
        }
    }

    #[test]
    fn zero_move_has_zero_duration() {
        let arm = ArmModel::ur5e();
        let q = arm.home_rad;
        let t = JointTrajectory::point_to_point(&arm, &q, &q).unwrap();
        assert_eq!(t.duration_s(), 0.0);
        assert_eq!(t.sample(0.0), q);
        assert_eq!(t.sample(1.0), q);
    }

    #[test]
    fn monotone_tangents_stay_in_range() {
        let waypoints = vec![
            [0.0; DOF],
            [1.0, 0.0, -1.0, 0.5, 0.0, 0.0],
            [1.1, 1.0, -1.2, 0.4, 0.0, 0.0],
            [3.0, 1.0, -1.3, 0.6, 0.0, 0.0],
        ];
        let knots = vec![0.0, 1.0, 2.0, 3.0];
        let tangents = monotone_tangents(&waypoints, &knots);
        let traj = JointTrajectory {
            knots_s: knots,
            waypoints: waypoints.clone(),
            tangents,
            profile: Trapezoid::new(3.0, 1.0, 1.0),
        };
        for i in 0..=3000 {
            let s = i as f64 / 1000.0;
            let k = (s.floor() as usize).min(2);
            let (q, _, _) = traj.path(s);
            for j in 0..DOF {
                let lo = waypoints[k][j].min(waypoints[k + 1][j]);
                let hi = waypoints[k][j].max(waypoints[k + 1][j]);
                assert!(q[j] >= lo - 1e-12 && q[j] <= hi + 1e-12, "s {s} joint {j}");
            }
        }
    }

    #[test]
    fn linear_move_parameters_validated() {
        let p = LinearMove {
            speed_m_s: 0.0,
            ..LinearMove::default()
        };
        assert!(matches!(
            p.validate(),
            Err(MotionError::InvalidParameter {
                field: "speed_m_s",
                ..
            })
        ));
    }
}
