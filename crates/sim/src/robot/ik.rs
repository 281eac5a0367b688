//! Inverse kinematics as a sequence of small quadratic programs solved with clarabel.
//!
//! Each iteration solves, for the joint step `Δq` (world-frame error `e = [p* − p; log(R* Rᵀ)]`,
//! Jacobian `J`, weights `W = diag(1, 1, 1, w, w, w)`):
//!
//! ```text
//! min ½ Δqᵀ (JᵀWJ + (λ² + μₖ) I) Δq − (JᵀW e + μₖ (q_seed − q))ᵀ Δq
//! s.t. max(q_min − q, −s) ≤ Δq ≤ min(q_max − q, s)
//! ```
//!
//! — damped least squares (λ) with a posture term toward the seed (or a configured rest
//! posture; `q_seed` above) whose weight
//! `μₖ = μ·min(1, ‖e‖)` fades as the error vanishes (so it never biases the converged pose), and
//! box constraints from the joint limits and a per-iteration step limit `s`. Every bound is
//! finite, presolve and equilibration are off, so one clarabel solver is built once and reused
//! for every iteration of every call through `update_P` / `update_q` / `update_b` (the
//! constraint matrix never changes). The loop stops when the position error is below
//! 0.1 mm and the orientation error below 0.05° (defaults), or after `max_iterations`.
//!
//! The solve starts at the seed (the current joints). Only if that fails does it restart from
//! the home posture and from the home posture turned toward the target; among converged
//! solutions the one nearest the seed wins, and each joint is moved by ±2π toward the seed when
//! its limits allow. A target no start reaches is an error: [`IkError::Unreachable`], or
//! [`IkError::JointLimits`] when the same target converges once the limits are widened by 2π.
//!
//! ```
//! use lgdm_sim::robot::arm::ArmModel;
//! use lgdm_sim::robot::ik::{IkConfig, IkSolver, IkTarget, TopDownGrasp};
//! let arm = ArmModel::ur5e();
//! let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
//! let target = IkTarget::TopDown(TopDownGrasp::new([0.5, 0.1, 0.05], 0.3));
//! let solution = ik.solve(&target, &arm.home_rad).unwrap();
//! assert!(solution.position_error_m < 1e-4);
//! let reached = arm.world_from_tool(&solution.joints_rad).unwrap();
//! assert!((reached.translation.vector - nalgebra::Vector3::new(0.5, 0.1, 0.05)).norm() < 1e-4);
//! ```

use crate::robot::arm::{ArmModel, ArmModelError, DOF, Joints, JointsError};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
};
use nalgebra::{Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Tuning of the IK iterations. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IkConfig {
    /// Damping λ of the least-squares step (default 0.02).
    pub damping: f64,
    /// Posture weight μ pulling toward the seed, faded by the error norm (default 1e-3).
    pub posture_weight: f64,
    /// Weight `w` of the orientation error rows relative to the position rows, in m²/rad²
    /// (default 0.3).
    pub orientation_weight: f64,
    /// Largest change of any joint in one iteration (rad; default 0.3).
    pub max_step_rad: f64,
    /// Iterations per start before giving up (default 150).
    pub max_iterations: u32,
    /// Convergence: position error below this (m; default 1e-4 = 0.1 mm).
    pub position_tolerance_m: f64,
    /// Convergence: orientation error below this (rad; default 0.05° ≈ 8.73e-4).
    pub orientation_tolerance_rad: f64,
    /// When the seed does not converge, retry from the home posture (default true).
    pub restarts: bool,
    /// Posture the posture term pulls toward (rad; default none: the seed, i.e. the current
    /// joints). Must lie within the arm's limits.
    pub rest_rad: Option<Joints>,
}

impl Default for IkConfig {
    fn default() -> Self {
        Self {
            damping: 0.02,
            posture_weight: 1e-3,
            orientation_weight: 0.3,
            max_step_rad: 0.3,
            max_iterations: 150,
            position_tolerance_m: 1e-4,
            orientation_tolerance_rad: 0.05_f64.to_radians(),
            restarts: true,
            rest_rad: None,
        }
    }
}

impl IkConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), IkError> {
        let positive = [
            ("damping", self.damping),
            ("orientation_weight", self.orientation_weight),
            ("max_step_rad", self.max_step_rad),
            ("position_tolerance_m", self.position_tolerance_m),
            ("orientation_tolerance_rad", self.orientation_tolerance_rad),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(IkError::InvalidConfig { field, value });
            }
        }
        if !(self.posture_weight.is_finite() && self.posture_weight >= 0.0) {
            return Err(IkError::InvalidConfig {
                field: "posture_weight",
                value: self.posture_weight,
            });
        }
        if self.max_iterations == 0 {
            return Err(IkError::InvalidConfig {
                field: "max_iterations",
                value: 0.0,
            });
        }
        Ok(())
    }
}

/// A top-down grasp: the tool z axis points straight down (−Z world) and the tool x axis (the
/// jaws' opening direction) points along `(cos yaw, sin yaw, 0)` in the world.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TopDownGrasp {
    /// Tool centre point in the world (m).
    pub position_m: [f64; 3],
    /// Rotation of the jaws about world Z (rad).
    pub yaw_rad: f64,
    /// The jaws are symmetric: `yaw + π` is the same grasp, and the one nearer the seed is
    /// taken (default true in [`TopDownGrasp::new`]).
    pub jaw_symmetric: bool,
}

impl TopDownGrasp {
    /// A jaw-symmetric top-down grasp at `position_m` with jaw yaw `yaw_rad`.
    pub fn new(position_m: [f64; 3], yaw_rad: f64) -> Self {
        Self {
            position_m,
            yaw_rad,
            jaw_symmetric: true,
        }
    }

    /// The tool pose of this grasp at yaw `yaw_rad` (ignores `self.yaw_rad`).
    fn pose_at_yaw(&self, yaw_rad: f64) -> Isometry3<f64> {
        let [x, y, z] = self.position_m;
        Isometry3::from_parts(Translation3::new(x, y, z), top_down_rotation(yaw_rad))
    }

    /// The tool pose (`world_from_tool`) of this grasp.
    pub fn world_from_tool(&self) -> Isometry3<f64> {
        self.pose_at_yaw(self.yaw_rad)
    }
}

/// `Rz(yaw)·Rx(π)`: tool z down, tool x at `yaw` in the world's XY plane.
pub fn top_down_rotation(yaw_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI)
}

/// What the tool should reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// A full 6-D tool pose in the world (`world_from_tool`).
    Pose(Isometry3<f64>),
    /// A top-down grasp.
    TopDown(TopDownGrasp),
}

/// A converged IK solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSolution {
    /// Joint positions, inside the limits (rad).
    pub joints_rad: Joints,
    /// Distance between the reached and the target TCP position (m).
    pub position_error_m: f64,
    /// Angle between the reached and the target orientation (rad).
    pub orientation_error_rad: f64,
    /// QP iterations spent, over every start tried.
    pub iterations: u32,
}

/// Why IK gave no solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// The target has a NaN or infinite component, or a rotation that is not a unit quaternion.
    #[error("IK target is invalid: {reason}")]
    InvalidTarget {
        /// What is wrong.
        reason: &'static str,
    },
    /// The seed joints are NaN or outside the limits.
    #[error("IK seed: {0}")]
    Seed(#[from] JointsError),
    /// No start converged, and none converges with the joint limits widened either: the pose
    /// lies out of the arm's reach (errors of the best attempt).
    #[error(
        "target unreachable: best attempt is {position_error_m} m and {orientation_error_rad} rad away"
    )]
    Unreachable {
        /// Position error of the best attempt (m).
        position_error_m: f64,
        /// Orientation error of the best attempt (rad).
        orientation_error_rad: f64,
    },
    /// The pose is reachable only with a joint beyond its limits (errors of the best in-limit
    /// attempt; `joints` are those that end beyond a limit in the widened solve).
    #[error(
        "target needs joints {joints:?} beyond their limits: best in-limit attempt is {position_error_m} m and {orientation_error_rad} rad away"
    )]
    JointLimits {
        /// Joints beyond their limits in the widened solution.
        joints: Vec<usize>,
        /// Position error of the best in-limit attempt (m).
        position_error_m: f64,
        /// Orientation error of the best in-limit attempt (rad).
        orientation_error_rad: f64,
    },
    /// A bad [`IkConfig`] field.
    #[error("IK config: {field} = {value} is invalid")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// A bad arm model.
    #[error(transparent)]
    Model(#[from] ArmModelError),
    /// clarabel failed on every attempt (setup error or numerical failure).
    #[error("QP solver failed: {0}")]
    Solver(String),
}

/// Number of constraint rows: an upper and a lower bound per joint.
const ROWS: usize = 2 * DOF;
/// Non-zeros of the upper triangle of the 6×6 Hessian.
const P_NNZ: usize = DOF * (DOF + 1) / 2;

/// The reused clarabel problem: `P` (dense upper triangle), `q`, constant `A = [I; −I]`, `b`.
struct Qp {
    solver: DefaultSolver<f64>,
    p_values: Vec<f64>,
    q_values: Vec<f64>,
    b_values: Vec<f64>,
}

impl Qp {
    fn new() -> Result<Self, IkError> {
        // Dense upper-triangular pattern, column by column (explicit zeros are kept).
        let mut colptr = vec![0usize];
        let mut rowval = Vec::with_capacity(P_NNZ);
        let mut nzval = Vec::with_capacity(P_NNZ);
        for c in 0..DOF {
            for r in 0..=c {
                rowval.push(r);
                nzval.push(if r == c { 1.0 } else { 0.0 });
            }
            colptr.push(rowval.len());
        }
        let p = CscMatrix::new(DOF, DOF, colptr, rowval, nzval.clone());
        // A = [I; −I]: column j holds +1 in row j and −1 in row DOF + j.
        let mut a_colptr = vec![0usize];
        let mut a_rowval = Vec::with_capacity(ROWS);
        let mut a_nzval = Vec::with_capacity(ROWS);
        for j in 0..DOF {
            a_rowval.extend([j, DOF + j]);
            a_nzval.extend([1.0, -1.0]);
            a_colptr.push(a_rowval.len());
        }
        let a = CscMatrix::new(ROWS, DOF, a_colptr, a_rowval, a_nzval);
        let q = vec![0.0; DOF];
        let b = vec![1.0; ROWS];
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .presolve_enable(false)
            .equilibrate_enable(false)
            .max_iter(100)
            .build()
            .map_err(|e| IkError::Solver(format!("settings: {e}")))?;
        let solver = DefaultSolver::new(&p, &q, &a, &b, &[NonnegativeConeT(ROWS)], settings)
            .map_err(|e| IkError::Solver(format!("setup: {e}")))?;
        if !solver.is_data_update_allowed() {
            return Err(IkError::Solver("clarabel refuses data updates".into()));
        }
        Ok(Self {
            solver,
            p_values: nzval,
            q_values: q,
            b_values: b,
        })
    }

    /// Solves `min ½xᵀHx + gᵀx s.t. lower ≤ x ≤ upper`; `None` if clarabel does not solve it.
    fn solve(
        &mut self,
        h: &Matrix6<f64>,
        g: &Vector6<f64>,
        lower: &Joints,
        upper: &Joints,
    ) -> Result<Vector6<f64>, String> {
        let mut k = 0;
        for c in 0..DOF {
            for r in 0..=c {
                self.p_values[k] = h[(r, c)];
                k += 1;
            }
        }
        for j in 0..DOF {
            self.q_values[j] = g[j];
            self.b_values[j] = upper[j];
            self.b_values[DOF + j] = -lower[j];
        }
        self.solver
            .update_P(&self.p_values)
            .and_then(|()| self.solver.update_q(&self.q_values))
            .and_then(|()| self.solver.update_b(&self.b_values))
            .map_err(|e| format!("update: {e}"))?;
        self.solver.solve();
        let sol = &self.solver.solution;
        match sol.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved
                if sol.x.iter().all(|v| v.is_finite()) =>
            {
                Ok(Vector6::from_column_slice(&sol.x))
            }
            status => Err(format!("status {status:?}")),
        }
    }
}

/// The IK solver for one arm: holds the arm model, the config and a reused clarabel problem.
pub struct IkSolver {
    model: ArmModel,
    config: IkConfig,
    qp: Qp,
}

impl std::fmt::Debug for IkSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IkSolver")
            .field("model", &self.model)
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

/// The outcome of one start.
struct Attempt {
    q: Joints,
    position_error_m: f64,
    orientation_error_rad: f64,
    converged: bool,
    qp_failure: Option<String>,
    iterations: u32,
    /// Some iteration's box was cut by a joint limit (not only by the step limit).
    limit_active: bool,
}

impl Attempt {
    /// Weighted error used to rank failed attempts.
    fn score(&self, orientation_weight: f64) -> f64 {
        self.position_error_m.powi(2) + orientation_weight * self.orientation_error_rad.powi(2)
    }
}

impl IkSolver {
    /// Validates the model and config and sets up the QP.
    pub fn new(model: ArmModel, config: IkConfig) -> Result<Self, IkError> {
        model.validate()?;
        config.validate()?;
        if let Some(rest) = &config.rest_rad
            && let Err(JointsError::NonFinite { joint } | JointsError::OutsideLimits { joint, .. }) =
                model.check_joints(rest)
        {
            return Err(IkError::InvalidConfig {
                field: "rest_rad",
                value: rest[joint],
            });
        }
        Ok(Self {
            model,
            config,
            qp: Qp::new()?,
        })
    }

    /// The arm model.
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The config.
    pub fn config(&self) -> &IkConfig {
        &self.config
    }

    /// Joints that put the tool on `target`, starting from (and nearest to) `seed_rad`.
    pub fn solve(&mut self, target: &IkTarget, seed_rad: &Joints) -> Result<IkSolution, IkError> {
        self.model.check_joints(seed_rad)?;
        match target {
            IkTarget::Pose(pose) => {
                check_pose(pose)?;
                self.solve_pose(pose, seed_rad, self.config.restarts)
            }
            IkTarget::TopDown(grasp) => {
                if !grasp.position_m.iter().all(|v| v.is_finite()) || !grasp.yaw_rad.is_finite() {
                    return Err(IkError::InvalidTarget {
                        reason: "top-down grasp has a non-finite position or yaw",
                    });
                }
                let first = self.solve_pose(
                    &grasp.pose_at_yaw(grasp.yaw_rad),
                    seed_rad,
                    self.config.restarts,
                );
                if !grasp.jaw_symmetric {
                    return first;
                }
                let second = self.solve_pose(
                    &grasp.pose_at_yaw(grasp.yaw_rad + PI),
                    seed_rad,
                    self.config.restarts,
                );
                match (first, second) {
                    (Ok(a), Ok(b)) => {
                        let iterations = a.iterations + b.iterations;
                        let pick = if joint_distance(&b.joints_rad, seed_rad)
                            < joint_distance(&a.joints_rad, seed_rad)
                        {
                            b
                        } else {
                            a
                        };
                        Ok(IkSolution { iterations, ..pick })
                    }
                    (Ok(a), Err(_)) => Ok(a),
                    (Err(_), Ok(b)) => Ok(b),
                    (Err(e), Err(_)) => Err(e),
                }
            }
        }
    }

    /// Joints for a full tool pose from the seed only: no restarts, so the solution stays on the
    /// seed's branch (used for waypoints of straight-line moves).
    pub fn solve_local(
        &mut self,
        world_from_tool: &Isometry3<f64>,
        seed_rad: &Joints,
    ) -> Result<IkSolution, IkError> {
        self.model.check_joints(seed_rad)?;
        check_pose(world_from_tool)?;
        self.solve_pose(world_from_tool, seed_rad, false)
    }

    fn solve_pose(
        &mut self,
        target: &Isometry3<f64>,
        seed: &Joints,
        restarts: bool,
    ) -> Result<IkSolution, IkError> {
        let (min, max) = (self.model.joint_min_rad, self.model.joint_max_rad);
        let posture = self.config.rest_rad.unwrap_or(*seed);
        let mut iterations = 0;
        let first = self.attempt(target, seed, &posture, &min, &max);
        iterations += first.iterations;
        if first.converged {
            return Ok(self.finish(&first, seed, iterations));
        }
        let mut attempts = vec![first];
        if restarts {
            for start in self.restart_seeds(target) {
                let a = self.attempt(target, &start, &posture, &min, &max);
                iterations += a.iterations;
                attempts.push(a);
            }
        }
        let best_converged = attempts
            .iter()
            .filter(|a| a.converged)
            .map(|a| (joint_distance(&self.wrap_toward(&a.q, seed), seed), a))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((_, a)) = best_converged {
            return Ok(self.finish(a, seed, iterations));
        }
        let w = self.config.orientation_weight;
        let best = attempts
            .iter()
            .filter(|a| a.qp_failure.is_none())
            .min_by(|x, y| x.score(w).total_cmp(&y.score(w)));
        let Some(best) = best else {
            let reason = attempts
                .iter()
                .find_map(|a| a.qp_failure.clone())
                .unwrap_or_default();
            return Err(IkError::Solver(reason));
        };
        if !attempts.iter().any(|a| a.limit_active) {
            // No joint limit ever cut a step: widened limits would repeat the same iterations.
            return Err(IkError::Unreachable {
                position_error_m: best.position_error_m,
                orientation_error_rad: best.orientation_error_rad,
            });
        }
        // Diagnose: does the target converge with the limits widened by a full turn?
        let wide_min = min.map(|v| v - 2.0 * PI);
        let wide_max = max.map(|v| v + 2.0 * PI);
        let mut starts = vec![*seed];
        if restarts {
            starts.extend(self.restart_seeds(target));
        }
        for start in starts {
            let wide = self.attempt(target, &start, &posture, &wide_min, &wide_max);
            iterations += wide.iterations;
            let wrapped = self.wrap_toward(&wide.q, seed);
            if wide.converged && self.model.check_joints(&wrapped).is_ok() {
                // The wider box let the iterations take another path to an in-limit solution.
                return Ok(self.finish(&wide, seed, iterations));
            }
            if wide.converged {
                let joints: Vec<usize> = (0..DOF)
                    .filter(|&j| wrapped[j] < min[j] || wrapped[j] > max[j])
                    .collect();
                if !joints.is_empty() {
                    return Err(IkError::JointLimits {
                        joints,
                        position_error_m: best.position_error_m,
                        orientation_error_rad: best.orientation_error_rad,
                    });
                }
            }
        }
        Err(IkError::Unreachable {
            position_error_m: best.position_error_m,
            orientation_error_rad: best.orientation_error_rad,
        })
    }

    /// Deterministic restarts: the home posture, and the home posture turned so that the arm
    /// faces the target.
    fn restart_seeds(&self, target: &Isometry3<f64>) -> Vec<Joints> {
        let home = self.model.home_rad;
        let base_from_world = self.model.world_from_base.to_isometry().inverse();
        let p = base_from_world * target.translation.vector;
        let home_tool = self.model.forward_unchecked(&home).world_from_tool;
        let h = base_from_world * home_tool.translation.vector;
        let mut turned = home;
        let delta = wrap_pi(p.y.atan2(p.x) - h.y.atan2(h.x));
        turned[0] = self.clamp_joint(0, home[0] + delta);
        vec![home, turned]
    }

    fn clamp_joint(&self, j: usize, v: f64) -> f64 {
        v.clamp(self.model.joint_min_rad[j], self.model.joint_max_rad[j])
    }

    /// One damped, posture-regularised QP iteration loop from `start`.
    fn attempt(
        &mut self,
        target: &Isometry3<f64>,
        start: &Joints,
        posture: &Joints,
        min: &Joints,
        max: &Joints,
    ) -> Attempt {
        let cfg = &self.config;
        let w = cfg.orientation_weight;
        let weights = Vector6::new(1.0, 1.0, 1.0, w, w, w);
        let lambda2 = cfg.damping * cfg.damping;
        let mut q = *start;
        let mut best_score = f64::INFINITY;
        let mut since_best = 0u32;
        let mut iterations = 0u32;
        let mut limit_active = false;
        loop {
            let pose = self.model.forward_unchecked(&q);
            let (e, pos_err, ori_err) = pose_error(&pose.world_from_tool, target);
            let converged =
                pos_err < cfg.position_tolerance_m && ori_err < cfg.orientation_tolerance_rad;
            let score = pos_err * pos_err + w * ori_err * ori_err;
            if score < best_score * (1.0 - 1e-3) {
                best_score = score;
                since_best = 0;
            } else {
                since_best += 1;
            }
            if converged || iterations >= cfg.max_iterations || since_best > 20 {
                return Attempt {
                    q,
                    position_error_m: pos_err,
                    orientation_error_rad: ori_err,
                    converged,
                    qp_failure: None,
                    iterations,
                    limit_active,
                };
            }
            let jac = pose.jacobian();
            let jt_w = jac.transpose() * Matrix6::from_diagonal(&weights);
            let err_norm = e.component_mul(&weights).dot(&e).sqrt();
            let mu = cfg.posture_weight * err_norm.min(1.0);
            let h = jt_w * jac + Matrix6::from_diagonal_element(lambda2 + mu);
            let posture_pull = Vector6::from_fn(|j, _| wrap_pi(posture[j] - q[j]));
            let g = -(jt_w * e + posture_pull * mu);
            let lower: Joints =
                std::array::from_fn(|j| (min[j] - q[j]).max(-cfg.max_step_rad).min(0.0));
            let upper: Joints =
                std::array::from_fn(|j| (max[j] - q[j]).min(cfg.max_step_rad).max(0.0));
            limit_active |= (0..DOF)
                .any(|j| min[j] - q[j] > -cfg.max_step_rad || max[j] - q[j] < cfg.max_step_rad);
            iterations += 1;
            match self.qp.solve(&h, &g, &lower, &upper) {
                Ok(dq) => {
                    for j in 0..DOF {
                        q[j] = (q[j] + dq[j]).clamp(min[j], max[j]);
                    }
                }
                Err(reason) => {
                    return Attempt {
                        q,
                        position_error_m: pos_err,
                        orientation_error_rad: ori_err,
                        converged: false,
                        qp_failure: Some(reason),
                        iterations,
                        limit_active,
                    };
                }
            }
        }
    }

    /// Moves each joint by whole turns toward the seed (within limits) and reports the errors.
    fn finish(&self, a: &Attempt, seed: &Joints, iterations: u32) -> IkSolution {
        IkSolution {
            joints_rad: self.wrap_toward(&a.q, seed),
            position_error_m: a.position_error_m,
            orientation_error_rad: a.orientation_error_rad,
            iterations,
        }
    }

    /// The 2π-equivalent of each joint of `q` that lies within the limits and is nearest
    /// `seed` (the joint unchanged if no equivalent is within the limits).
    fn wrap_toward(&self, q: &Joints, seed: &Joints) -> Joints {
        std::array::from_fn(|j| {
            let (min, max) = (self.model.joint_min_rad[j], self.model.joint_max_rad[j]);
            let mut best: Option<f64> = None;
            for k in [-2.0, -1.0, 0.0, 1.0, 2.0] {
                let v = q[j] + k * 2.0 * PI;
                let closer = best.is_none_or(|b| (v - seed[j]).abs() < (b - seed[j]).abs());
                if v >= min && v <= max && closer {
                    best = Some(v);
                }
            }
            best.unwrap_or(q[j])
        })
    }
}

/// World-frame pose error `[p* − p; log(R* Rᵀ)]`, its position norm (m) and rotation angle (rad).
pub fn pose_error(
    world_from_tool: &Isometry3<f64>,
    target: &Isometry3<f64>,
) -> (Vector6<f64>, f64, f64) {
    let dp = target.translation.vector - world_from_tool.translation.vector;
    let dr = target.rotation * world_from_tool.rotation.inverse();
    let dw = dr.scaled_axis();
    let e = Vector6::new(dp.x, dp.y, dp.z, dw.x, dw.y, dw.z);
    (e, dp.norm(), dr.angle())
}

pub(crate) fn check_pose(pose: &Isometry3<f64>) -> Result<(), IkError> {
    let t = &pose.translation.vector;
    let r = pose.rotation.coords;
    if !t.iter().chain(r.iter()).all(|v| v.is_finite()) {
        return Err(IkError::InvalidTarget {
            reason: "pose has a non-finite component",
        });
    }
    if (r.norm() - 1.0).abs() > 1e-6 {
        return Err(IkError::InvalidTarget {
            reason: "pose rotation is not a unit quaternion",
        });
    }
    Ok(())
}

/// Euclidean distance between two joint vectors (rad).
fn joint_distance(a: &Joints, b: &Joints) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Wraps an angle to (−π, π].
fn wrap_pi(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI);
    if w > PI { w - 2.0 * PI } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_down_rotation_points_down() {
        for yaw in [0.0, 0.7, -2.0, PI] {
            let r = top_down_rotation(yaw);
            let z = r * Vector3::z();
            let x = r * Vector3::x();
            assert!((z - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
            assert!((x - Vector3::new(yaw.cos(), yaw.sin(), 0.0)).norm() < 1e-12);
        }
    }

    #[test]
    fn config_validation_names_field() {
        let cfg = IkConfig {
            max_step_rad: -1.0,
            ..IkConfig::default()
        };
        assert!(matches!(
            cfg.validate(),
            Err(IkError::InvalidConfig {
                field: "max_step_rad",
                ..
            })
        ));
        let cfg = IkConfig {
            damping: f64::NAN,
            ..IkConfig::default()
        };
        assert!(IkSolver::new(ArmModel::ur5e(), cfg).is_err());
    }

    #[test]
    fn config_serde_defaults_and_rest_posture() {
        let empty: IkConfig = serde_json::from_str("{}").unwrap();
        assert_eq!(empty, IkConfig::default());
        assert!(serde_json::from_str::<IkConfig>(r#"{"dampin": 0.1}"#).is_err());
        let arm = ArmModel::ur5e();
        let mut rest = arm.home_rad;
        rest[2] = 4.0;
        let cfg = IkConfig {
            rest_rad: Some(rest),
            ..IkConfig::default()
        };
        assert!(matches!(
            IkSolver::new(arm.clone(), cfg),
            Err(IkError::InvalidConfig {
                field: "rest_rad",
                ..
            })
        ));
        // A rest posture is only a preference: the target is still met.
        let cfg = IkConfig {
            rest_rad: Some(arm.home_rad),
            ..IkConfig::default()
        };
        let mut ik = IkSolver::new(arm.clone(), cfg).unwrap();
        let grasp = TopDownGrasp::new([0.5, 0.2, 0.1], 0.5);
        let seed = [0.0, -1.0, 1.0, -1.0, -1.0, 0.0];
        let sol = ik.solve(&IkTarget::TopDown(grasp), &seed).unwrap();
        assert!(sol.position_error_m < 1e-4 && sol.orientation_error_rad < 1e-3);
    }

    /// The sim may run attempts on worker threads.
    #[test]
    fn solver_is_send() {
        fn send<T: Send>() {}
        send::<IkSolver>();
    }

    #[test]
    fn wrap_pi_range() {
        for a in [-7.0, -PI, -1.0, 0.0, 1.0, PI, 4.0, 10.0] {
            let w = wrap_pi(a);
            assert!(w > -PI - 1e-12 && w <= PI + 1e-12);
            assert!(
                ((a - w) / (2.0 * PI)).fract().abs() < 1e-9
                    || ((a - w) / (2.0 * PI)).fract().abs() > 1.0 - 1e-9
            );
        }
    }

    /// The QP respects its box and solves an unconstrained problem exactly.
    #[test]
    fn qp_box_and_unconstrained() {
        let mut qp = Qp::new().unwrap();
        let h = Matrix6::identity() * 2.0;
        let g = Vector6::new(-1.0, 1.0, -10.0, 0.0, 0.5, 4.0);
        let lower = [-1.0; DOF];
        let upper = [1.0; DOF];
        let x = qp.solve(&h, &g, &lower, &upper).unwrap();
        // Unconstrained optimum −g/2 = (0.5, −0.5, 5, 0, −0.25, −2) clipped to [−1, 1].
        let expected = [0.5, -0.5, 1.0, 0.0, -0.25, -1.0];
        for j in 0..DOF {
            assert!((x[j] - expected[j]).abs() < 1e-6, "{j}: {}", x[j]);
        }
    }

    #[test]
    fn seed_outside_limits_is_an_error() {
        let arm = ArmModel::ur5e();
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
        let mut seed = arm.home_rad;
        seed[2] = 3.5;
        let target = IkTarget::TopDown(TopDownGrasp::new([0.5, 0.0, 0.1], 0.0));
        assert!(matches!(
            ik.solve(&target, &seed),
            Err(IkError::Seed(JointsError::OutsideLimits { joint: 2, .. }))
        ));
    }

    #[test]
    fn non_unit_rotation_is_an_error() {
        let arm = ArmModel::ur5e();
        let mut ik = IkSolver::new(arm.clone(), IkConfig::default()).unwrap();
        let bad = Isometry3::from_parts(
            Translation3::new(0.4, 0.0, 0.2),
            UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0)),
        );
        assert!(matches!(
            ik.solve(&IkTarget::Pose(bad), &arm.home_rad),
            Err(IkError::InvalidTarget { .. })
        ));
    }
}
