//! The round's memory of failed grasps: where grasps failed, in the world frame, so the robot
//! does not try the same grasp again in the round.
//!
//! A grasp is its centre (m, world) and the direction of its jaws' opening axis about world z; a
//! parallel jaw is symmetric, so yaws a half turn apart are the same grasp. A candidate whose
//! centre lies within [`FailedGrasps::radius_m`] of a failed grasp's and whose axis lies within
//! [`FailedGrasps::angle_deg`] of its axis (modulo 180°) [covers](FailedGrasps::covers) it: the
//! runner skips it as it would skip a candidate ranked lower. A radius of 0 switches the memory
//! off.
//!
//! ```
//! use lgdm_sim::grasping::failed::FailedGrasps;
//! let mut failed = FailedGrasps::new(0.02, 15.0);
//! failed.remember([0.05, -0.52, 0.85], 0.3);
//! // The same place, the jaws turned a half turn: the same grasp.
//! assert!(failed.covers([0.06, -0.52, 0.85], 0.3 + std::f64::consts::PI));
//! // Farther than 2 cm: another grasp.
//! assert!(!failed.covers([0.08, -0.52, 0.85], 0.3));
//! ```

use std::f64::consts::PI;

/// Failed grasps of one round, and how near a candidate must be to one of them to count as it.
#[derive(Debug, Clone, PartialEq)]
pub struct FailedGrasps {
    radius_m: f64,
    angle_deg: f64,
    /// Centre (m, world) and axis yaw (rad) of each failed grasp, in the order they failed.
    failed: Vec<([f64; 3], f64)>,
}

impl FailedGrasps {
    /// An empty memory that counts a candidate as a failed grasp when its centre is within
    /// `radius_m` of that grasp's and its axis within `angle_deg` of it (modulo 180°); radius 0:
    /// off (it covers nothing).
    pub fn new(radius_m: f64, angle_deg: f64) -> Self {
        Self {
            radius_m,
            angle_deg,
            failed: Vec::new(),
        }
    }

    /// Whether the memory is on (a positive radius).
    pub fn is_on(&self) -> bool {
        self.radius_m > 0.0
    }

    /// The radius (m).
    pub fn radius_m(&self) -> f64 {
        self.radius_m
    }

    /// The angle (degrees).
    pub fn angle_deg(&self) -> f64 {
        self.angle_deg
    }

    /// Remembers a grasp that failed: centre `position_m` (m, world), jaw axis `yaw_rad`.
    pub fn remember(&mut self, position_m: [f64; 3], yaw_rad: f64) {
        if self.is_on() {
            self.failed.push((position_m, yaw_rad));
        }
    }

    /// Whether a grasp at `position_m` with jaw axis `yaw_rad` is one that failed (see the
    /// module docs); never when the memory is off.
    pub fn covers(&self, position_m: [f64; 3], yaw_rad: f64) -> bool {
        self.is_on()
            && self.failed.iter().any(|(p, yaw)| {
                distance_m(*p, position_m) <= self.radius_m
                    && axis_angle_deg(*yaw, yaw_rad) <= self.angle_deg
            })
    }

    /// Forgets every grasp (a new round).
    pub fn clear(&mut self) {
        self.failed.clear();
    }
}

/// Euclidean distance (m).
fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The angle between two jaw axes given as yaws (rad), modulo a half turn: in [0°, 90°].
pub fn axis_angle_deg(a_rad: f64, b_rad: f64) -> f64 {
    let d = (a_rad - b_rad).rem_euclid(PI);
    d.min(PI - d).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_place_and_axis_modulo_a_half_turn_is_skipped() {
        let mut failed = FailedGrasps::new(0.02, 10.0);
        assert!(!failed.covers([0.0, 0.0, 0.8], 0.0), "nothing failed yet");
        failed.remember([0.0, 0.0, 0.8], 1.5);
        assert!(failed.covers([0.0, 0.0, 0.8], 1.5));
        // π apart (a parallel jaw turned over) and across the ±π seam.
        assert!(failed.covers([0.01, 0.01, 0.8], 1.5 - PI));
        assert!(failed.covers([0.0, 0.0, 0.8], 1.5 + PI + 0.1));
        failed.remember([0.0, 0.0, 0.8], PI - 0.05);
        assert!(failed.covers([0.0, 0.0, 0.8], -PI + 0.05));
    }

    #[test]
    fn farther_or_turned_further_is_tried() {
        let mut failed = FailedGrasps::new(0.02, 10.0);
        failed.remember([0.0, 0.0, 0.8], 0.0);
        assert!(!failed.covers([0.021, 0.0, 0.8], 0.0), "beyond the radius");
        assert!(
            !failed.covers([0.0, 0.0, 0.83], 0.0),
            "above it, beyond the radius"
        );
        assert!(
            !failed.covers([0.0, 0.0, 0.8], 11f64.to_radians()),
            "beyond the angle"
        );
        assert!(failed.covers([0.0, 0.0, 0.8], 9f64.to_radians()));
        failed.clear();
        assert!(!failed.covers([0.0, 0.0, 0.8], 0.0), "a new round forgets");
    }

    #[test]
    fn radius_zero_is_off() {
        let mut failed = FailedGrasps::new(0.0, 180.0);
        failed.remember([0.0, 0.0, 0.8], 0.0);
        assert!(!failed.is_on());
        assert!(!failed.covers([0.0, 0.0, 0.8], 0.0));
    }

    #[test]
    fn axis_angles_fold_into_a_quarter_turn() {
        assert!((axis_angle_deg(0.0, PI / 2.0) - 90.0).abs() < 1e-9);
        assert!(axis_angle_deg(0.2, 0.2 + PI).abs() < 1e-9);
        assert!((axis_angle_deg(-PI + 0.1, PI - 0.1) - 0.2f64.to_degrees()).abs() < 1e-9);
    }
}
