//! A six-joint UR-class arm: its kinematic model (standard DH table, base pose, tool offset,
//! joint limits, home posture), forward kinematics of every link, and the geometric Jacobian.
//!
//! Frames: `world_from_base` places the arm's DH base frame (z up along joint 1) in the world;
//! DH frame *i* (i = 1..6) is attached to link *i* and moved by joint *i*; frame 6 is the flange;
//! `flange_from_tool` puts the tool centre point (TCP, e.g. between the gripper's fingertips) on
//! the flange. Standard DH: `T_i = Rz(θ_i + offset_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`. The arm faces
//! +x of its base frame: the home posture holds the tool top-down ahead of the base on +x.
//!
//! ```
//! use lgdm_sim::robot::arm::ArmModel;
//! let arm = ArmModel::ur5e();
//! arm.validate().unwrap();
//! let q = arm.home_rad;
//! let world_from_tool = arm.world_from_tool(&q).unwrap();
//! // The home posture points the tool straight down.
//! let tool_z = world_from_tool.rotation * nalgebra::Vector3::z();
//! assert!((tool_z.z + 1.0).abs() < 1e-9);
//! ```

use nalgebra::{Isometry3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Number of joints of the arm.
pub const DOF: usize = 6;

/// Joint positions (rad), speeds (rad/s) or accelerations (rad/s²), one per joint, base first.
pub type Joints = [f64; DOF];

/// One row of a standard Denavit–Hartenberg table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhJoint {
    /// Link length `a_i` along the new x axis (m).
    pub a_m: f64,
    /// Link offset `d_i` along the previous z axis (m).
    pub d_m: f64,
    /// Link twist `α_i` about the new x axis (rad).
    pub alpha_rad: f64,
    /// Constant added to the joint angle, `θ_i = q_i + offset` (rad; default 0, as for UR arms).
    #[serde(default)]
    pub theta_offset_rad: f64,
}

impl DhJoint {
    /// The transform of this row at joint angle `q_rad`: `Rz(θ)·Tz(d)·Tx(a)·Rx(α)`.
    pub fn transform(&self, q_rad: f64) -> Isometry3<f64> {
        let theta = q_rad + self.theta_offset_rad;
        let (s, c) = theta.sin_cos();
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), theta)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), self.alpha_rad);
        Isometry3::from_parts(
            Translation3::new(self.a_m * c, self.a_m * s, self.d_m),
            rotation,
        )
    }
}

/// A rigid transform in a config file: a translation and roll/pitch/yaw angles.
///
/// The rotation is `Rz(yaw)·Ry(pitch)·Rx(roll)` (nalgebra's `from_euler_angles`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RigidTransform {
    /// Translation (m).
    pub translation_m: [f64; 3],
    /// Roll, pitch, yaw (rad).
    pub rotation_rpy_rad: [f64; 3],
}

impl RigidTransform {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        translation_m: [0.0; 3],
        rotation_rpy_rad: [0.0; 3],
    };

    /// A pure translation (m).
    pub fn from_translation_m(x_m: f64, y_m: f64, z_m: f64) -> Self {
        Self {
            translation_m: [x_m, y_m, z_m],
            rotation_rpy_rad: [0.0; 3],
        }
    }

    /// The transform as an isometry.
    pub fn to_isometry(&self) -> Isometry3<f64> {
        let [x, y, z] = self.translation_m;
        let [roll, pitch, yaw] = self.rotation_rpy_rad;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    /// The config form of an isometry.
    pub fn from_isometry(pose: &Isometry3<f64>) -> Self {
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        let t = pose.translation.vector;
        Self {
            translation_m: [t.x, t.y, t.z],
            rotation_rpy_rad: [roll, pitch, yaw],
        }
    }

    fn is_finite(&self) -> bool {
        self.translation_m
            .iter()
            .chain(self.rotation_rpy_rad.iter())
            .all(|v| v.is_finite())
    }
}

/// Which preset an [`ArmModel`] started from (informational; every field can be changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmKind {
    /// Universal Robots UR5e, official DH parameters (UR FAQ 45257).
    Ur5e,
    /// Universal Robots UR5 (CB3), the kinematics of the paper's pybullet URDF.
    Ur5Cb3,
    /// A user-defined arm.
    Custom,
}

/// The kinematic model of a six-joint arm. Defaults (`Default` = [`ArmModel::ur5e`]) are stated
/// per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmModel {
    /// Preset this model came from (default: `ur5e`).
    pub kind: ArmKind,
    /// Standard DH table, joint 1 first (default: the official UR5e table: d1 0.1625,
    /// a2 −0.425, a3 −0.3922, d4 0.1333, d5 0.0997, d6 0.0996, α = [π/2, 0, 0, π/2, −π/2, 0]).
    pub dh: [DhJoint; DOF],
    /// Pose of the DH base frame in the world (default: identity — the sim's world places it).
    pub world_from_base: RigidTransform,
    /// Pose of the tool centre point in the flange frame (default: 0.15 m along the flange z,
    /// a placeholder for a Robotiq-2F-85-class gripper; the gripper config should set its own).
    pub flange_from_tool: RigidTransform,
    /// Lower joint position limits (rad; default −2π, elbow −π).
    pub joint_min_rad: Joints,
    /// Upper joint position limits (rad; default +2π, elbow +π).
    pub joint_max_rad: Joints,
    /// Joint speed limits (rad/s; default π = 180°/s for every joint, the UR5e manual).
    pub max_speed_rad_s: Joints,
    /// Joint acceleration limits (rad/s²; default π = 180°/s², not published by UR).
    pub max_accel_rad_s2: Joints,
    /// Home posture (rad; default [`HOME_RAD`] ≈ [2.841, −1.714, 1.8, −1.657, −π/2, −1.871]: the
    /// tool points straight down about 0.45 m ahead of the base on +x, 0.30 m above the base
    /// plane with the default tool, jaw yaw 0, elbow up).
    pub home_rad: Joints,
}

impl Default for ArmModel {
    fn default() -> Self {
        Self::ur5e()
    }
}

/// Default tool offset along the flange z (m).
pub const DEFAULT_TOOL_LENGTH_M: f64 = 0.15;

const HALF_PI: f64 = PI / 2.0;

/// The presets' home posture (rad). Joints 2–4 sum to −π/2 and joint 5 is −π/2, which points the
/// tool z straight down on any UR-geometry arm; joint 6 = joint 1 + π/2 − 2π makes the jaw yaw 0
/// (tool x along base +x). On the UR5e with the default tool the TCP sits at about
/// (0.45, 0.00, 0.30) m in the base frame: ahead on +x, elbow up, wrist high above the base plane.
pub const HOME_RAD: Joints = [
    2.841,
    -1.714,
    1.8,
    -HALF_PI + 1.714 - 1.8,
    -HALF_PI,
    2.841 + HALF_PI - 2.0 * PI,
];

impl ArmModel {
    /// UR5e with the official DH table (UR FAQ 45257), ±2π limits (elbow ±π), 180°/s, 180°/s².
    pub fn ur5e() -> Self {
        Self::from_dh(
            ArmKind::Ur5e,
            [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996],
            [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0],
        )
    }

    /// UR5 (CB3): d1 0.089159, a2 −0.425, a3 −0.39225, d4 0.10915, d5 0.09465, d6 0.0823 — the
    /// kinematics of the paper's pybullet URDF. Same limits as [`ArmModel::ur5e`].
    pub fn ur5_cb3() -> Self {
        Self::from_dh(
            ArmKind::Ur5Cb3,
            [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823],
            [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0],
        )
    }

    fn from_dh(kind: ArmKind, d_m: Joints, a_m: Joints) -> Self {
        let alpha_rad = [HALF_PI, 0.0, 0.0, HALF_PI, -HALF_PI, 0.0];
        let dh = std::array::from_fn(|i| DhJoint {
            a_m: a_m[i],
            d_m: d_m[i],
            alpha_rad: alpha_rad[i],
            theta_offset_rad: 0.0,
        });
        let two_pi = 2.0 * PI;
        Self {
            kind,
            dh,
            world_from_base: RigidTransform::IDENTITY,
            flange_from_tool: RigidTransform::from_translation_m(0.0, 0.0, DEFAULT_TOOL_LENGTH_M),
            joint_min_rad: [-two_pi, -two_pi, -PI, -two_pi, -two_pi, -two_pi],
            joint_max_rad: [two_pi, two_pi, PI, two_pi, two_pi, two_pi],
            max_speed_rad_s: [PI; DOF],
            max_accel_rad_s2: [PI; DOF],
            home_rad: HOME_RAD,
        }
    }

    /// The same arm with its base at `world_from_base`.
    pub fn with_world_from_base(mut self, world_from_base: &Isometry3<f64>) -> Self {
        self.world_from_base = RigidTransform::from_isometry(world_from_base);
        self
    }

    /// The same arm with the tool centre point `length_m` along the flange z.
    pub fn with_tool_length_m(mut self, length_m: f64) -> Self {
        self.flange_from_tool = RigidTransform::from_translation_m(0.0, 0.0, length_m);
        self
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ArmModelError> {
        for (i, row) in self.dh.iter().enumerate() {
            for (name, v) in [
                ("a_m", row.a_m),
                ("d_m", row.d_m),
                ("alpha_rad", row.alpha_rad),
                ("theta_offset_rad", row.theta_offset_rad),
            ] {
                if !v.is_finite() {
                    return Err(ArmModelError::NonFinite {
                        field: format!("dh[{i}].{name}"),
                    });
                }
            }
        }
        if !self.world_from_base.is_finite() {
            return Err(ArmModelError::NonFinite {
                field: "world_from_base".into(),
            });
        }
        if !self.flange_from_tool.is_finite() {
            return Err(ArmModelError::NonFinite {
                field: "flange_from_tool".into(),
            });
        }
        for j in 0..DOF {
            let (min, max) = (self.joint_min_rad[j], self.joint_max_rad[j]);
            if !min.is_finite() || !max.is_finite() || min >= max {
                return Err(ArmModelError::BadLimits {
                    joint: j,
                    min_rad: min,
                    max_rad: max,
                });
            }
            if max - min > 4.0 * PI + 1e-9 {
                return Err(ArmModelError::LimitRangeTooWide {
                    joint: j,
                    range_rad: max - min,
                });
            }
            for (name, v) in [
                ("max_speed_rad_s", self.max_speed_rad_s[j]),
                ("max_accel_rad_s2", self.max_accel_rad_s2[j]),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(ArmModelError::NotPositive {
                        field: format!("{name}[{j}]"),
                        value: v,
                    });
                }
            }
            let h = self.home_rad[j];
            if !(h.is_finite() && h >= min && h <= max) {
                return Err(ArmModelError::HomeOutsideLimits {
                    joint: j,
                    value_rad: h,
                    min_rad: min,
                    max_rad: max,
                });
            }
        }
        Ok(())
    }

    /// Checks a joint vector: finite and inside the limits.
    pub fn check_joints(&self, q_rad: &Joints) -> Result<(), JointsError> {
        for (j, &v) in q_rad.iter().enumerate() {
            if !v.is_finite() {
                return Err(JointsError::NonFinite { joint: j });
            }
            if v < self.joint_min_rad[j] || v > self.joint_max_rad[j] {
                return Err(JointsError::OutsideLimits {
                    joint: j,
                    value_rad: v,
                    min_rad: self.joint_min_rad[j],
                    max_rad: self.joint_max_rad[j],
                });
            }
        }
        Ok(())
    }

    /// Forward kinematics of every frame at joints `q_rad` (finite values required; limits are
    /// not checked, see [`ArmModel::check_joints`]).
    pub fn forward(&self, q_rad: &Joints) -> Result<ArmPose, JointsError> {
        if let Some(joint) = q_rad.iter().position(|v| !v.is_finite()) {
            return Err(JointsError::NonFinite { joint });
        }
        Ok(self.forward_unchecked(q_rad))
    }

    /// The tool centre point's pose in the world at joints `q_rad`.
    pub fn world_from_tool(&self, q_rad: &Joints) -> Result<Isometry3<f64>, JointsError> {
        Ok(self.forward(q_rad)?.world_from_tool)
    }

    pub(crate) fn forward_unchecked(&self, q_rad: &Joints) -> ArmPose {
        let world_from_base = self.world_from_base.to_isometry();
        let mut current = world_from_base;
        let world_from_link = std::array::from_fn(|i| {
            current *= self.dh[i].transform(q_rad[i]);
            current
        });
        let world_from_flange = world_from_link[DOF - 1];
        ArmPose {
            world_from_base,
            world_from_link,
            world_from_flange,
            world_from_tool: world_from_flange * self.flange_from_tool.to_isometry(),
        }
    }

    /// Geometric Jacobian of the tool centre point in the world frame at joints `q_rad`: rows
    /// 0–2 map joint speeds to the TCP's linear velocity (m/s), rows 3–5 to its angular
    /// velocity (rad/s).
    pub fn jacobian(&self, q_rad: &Joints) -> Result<Matrix6<f64>, JointsError> {
        Ok(self.forward(q_rad)?.jacobian())
    }
}

/// All frames of the arm at one joint configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmPose {
    /// The DH base frame in the world.
    pub world_from_base: Isometry3<f64>,
    /// DH frames 1..6 in the world: `world_from_link[i]` poses link `i + 1` (the body moved by
    /// joint `i + 1`); `world_from_link[5]` is the flange.
    pub world_from_link: [Isometry3<f64>; DOF],
    /// The flange (DH frame 6) in the world.
    pub world_from_flange: Isometry3<f64>,
    /// The tool centre point in the world.
    pub world_from_tool: Isometry3<f64>,
}

impl ArmPose {
    /// Geometric Jacobian of the TCP in the world frame (see [`ArmModel::jacobian`]).
    pub fn jacobian(&self) -> Matrix6<f64> {
        let p_tool = Point3::from(self.world_from_tool.translation.vector);
        let mut jac = Matrix6::zeros();
        for i in 0..DOF {
            // Joint i turns about the z axis of the frame before it.
            let frame = if i == 0 {
                &self.world_from_base
            } else {
                &self.world_from_link[i - 1]
            };
            let axis = frame.rotation * Vector3::z();
            let origin = Point3::from(frame.translation.vector);
            let linear = axis.cross(&(p_tool - origin));
            jac.fixed_view_mut::<3, 1>(0, i).copy_from(&linear);
            jac.fixed_view_mut::<3, 1>(3, i).copy_from(&axis);
        }
        jac
    }
}

/// A bad [`ArmModel`] field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArmModelError {
    /// A value that must be finite is NaN or infinite.
    #[error("arm model: {field} is not finite")]
    NonFinite {
        /// The field, e.g. `dh[2].a_m`.
        field: String,
    },
    /// A joint's limits are not finite or not increasing.
    #[error(
        "arm model: joint_min_rad[{joint}] = {min_rad} must be finite and below joint_max_rad[{joint}] = {max_rad}"
    )]
    BadLimits {
        /// Joint index (0 = base).
        joint: usize,
        /// Lower limit (rad).
        min_rad: f64,
        /// Upper limit (rad).
        max_rad: f64,
    },
    /// A joint's range is wider than two turns (4π).
    #[error("arm model: joint {joint} range {range_rad} rad is wider than 4π")]
    LimitRangeTooWide {
        /// Joint index.
        joint: usize,
        /// `max − min` (rad).
        range_rad: f64,
    },
    /// A speed or acceleration limit is not a positive finite number.
    #[error("arm model: {field} = {value} must be positive and finite")]
    NotPositive {
        /// The field, e.g. `max_speed_rad_s[3]`.
        field: String,
        /// The value given.
        value: f64,
    },
    /// The home posture lies outside the joint limits.
    #[error("arm model: home_rad[{joint}] = {value_rad} is outside [{min_rad}, {max_rad}]")]
    HomeOutsideLimits {
        /// Joint index.
        joint: usize,
        /// The value given (rad).
        value_rad: f64,
        /// Lower limit (rad).
        min_rad: f64,
        /// Upper limit (rad).
        max_rad: f64,
    },
}

/// A bad joint vector.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointsError {
    /// A joint value is NaN or infinite.
    #[error("joint {joint} is not finite")]
    NonFinite {
        /// Joint index.
        joint: usize,
    },
    /// A joint value lies outside its limits.
    #[error("joint {joint} = {value_rad} rad is outside [{min_rad}, {max_rad}]")]
    OutsideLimits {
        /// Joint index.
        joint: usize,
        /// The value given (rad).
        value_rad: f64,
        /// Lower limit (rad).
        min_rad: f64,
        /// Upper limit (rad).
        max_rad: f64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate() {
        ArmModel::ur5e().validate().unwrap();
        ArmModel::ur5_cb3().validate().unwrap();
    }

    #[test]
    fn validate_names_the_field() {
        let mut arm = ArmModel::ur5e();
        arm.dh[2].a_m = f64::NAN;
        assert_eq!(
            arm.validate(),
            Err(ArmModelError::NonFinite {
                field: "dh[2].a_m".into()
            })
        );
        let mut arm = ArmModel::ur5e();
        arm.max_speed_rad_s[4] = 0.0;
        let err = arm.validate().unwrap_err();
        assert!(err.to_string().contains("max_speed_rad_s[4]"), "{err}");
        let mut arm = ArmModel::ur5e();
        arm.joint_min_rad[1] = 1.0;
        arm.joint_max_rad[1] = -1.0;
        assert!(matches!(
            arm.validate(),
            Err(ArmModelError::BadLimits { joint: 1, .. })
        ));
        let mut arm = ArmModel::ur5e();
        arm.home_rad[2] = 4.0;
        assert!(matches!(
            arm.validate(),
            Err(ArmModelError::HomeOutsideLimits { joint: 2, .. })
        ));
    }

    #[test]
    fn serde_roundtrip_and_defaults() {
        let arm = ArmModel::ur5_cb3().with_tool_length_m(0.2);
        let json = serde_json::to_string(&arm).unwrap();
        let back: ArmModel = serde_json::from_str(&json).unwrap();
        assert_eq!(arm, back);
        let empty: ArmModel = serde_json::from_str("{}").unwrap();
        assert_eq!(empty, ArmModel::ur5e());
        assert!(serde_json::from_str::<ArmModel>(r#"{"dh_typo": 1}"#).is_err());
    }

    #[test]
    fn rigid_transform_roundtrip() {
        let t = RigidTransform {
            translation_m: [0.1, -0.2, 0.3],
            rotation_rpy_rad: [0.3, -0.4, 1.2],
        };
        let back = RigidTransform::from_isometry(&t.to_isometry());
        for k in 0..3 {
            assert!((back.translation_m[k] - t.translation_m[k]).abs() < 1e-12);
            assert!((back.rotation_rpy_rad[k] - t.rotation_rpy_rad[k]).abs() < 1e-12);
        }
    }

    /// The Jacobian matches finite differences of forward kinematics.
    #[test]
    fn jacobian_matches_finite_differences() {
        let arm = ArmModel::ur5e().with_world_from_base(&Isometry3::new(
            Vector3::new(0.1, -0.3, 0.7),
            Vector3::new(0.0, 0.0, 0.6),
        ));
        let q = [0.3, -1.2, 1.4, -1.9, -1.4, 0.5];
        let jac = arm.jacobian(&q).unwrap();
        let h = 1e-6;
        let base = arm.world_from_tool(&q).unwrap();
        for j in 0..DOF {
            let mut qp = q;
            qp[j] += h;
            let moved = arm.world_from_tool(&qp).unwrap();
            let dp = (moved.translation.vector - base.translation.vector) / h;
            let dw = (moved.rotation * base.rotation.inverse()).scaled_axis() / h;
            for r in 0..3 {
                assert!((jac[(r, j)] - dp[r]).abs() < 1e-5, "linear {r},{j}");
                assert!((jac[(r + 3, j)] - dw[r]).abs() < 1e-5, "angular {r},{j}");
            }
        }
    }

    #[test]
    fn forward_rejects_nan() {
        let arm = ArmModel::ur5e();
        let mut q = arm.home_rad;
        q[3] = f64::NAN;
        assert_eq!(arm.forward(&q), Err(JointsError::NonFinite { joint: 3 }));
        assert!(arm.jacobian(&q).is_err());
    }

    #[test]
    fn check_joints_reports_limits() {
        let arm = ArmModel::ur5e();
        let mut q = arm.home_rad;
        assert!(arm.check_joints(&q).is_ok());
        q[2] = 3.2;
        assert!(matches!(
            arm.check_joints(&q),
            Err(JointsError::OutsideLimits { joint: 2, .. })
        ));
    }
}
