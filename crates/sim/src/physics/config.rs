//! Every constant of the physics world ([`WorldConfig`]: gravity, step, solver, contacts, the
//! table, the baskets, the objects' material, settling), each field's default stated, checked by
//! [`WorldConfig::validate`] (the error names the field, e.g. `table.size_m[2]`).

use serde::{Deserialize, Serialize};

use crate::physics::error::WorldError;

/// Which contact-friction model rapier solves (serde mirror of rapier's `FrictionModel`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionKind {
    /// One friction row per group of 4 contacts plus a twist row (rapier's default, faster).
    Simplified,
    /// One Coulomb friction row per contact point.
    Coulomb,
}

/// The fixed table: a box whose top face is the grasping surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TableConfig {
    /// Centre of the table-top box (m; default (0, −0.65, 0.76): the reference `table.urdf`
    /// placement).
    pub center_m: [f32; 3],
    /// Size of the table-top box along x, y, z (m; default 1.0 × 0.65 × 0.05, so the top is at
    /// z = 0.76 + 0.025 = 0.785 m, the reference `Z_TABLE_TOP`).
    pub size_m: [f32; 3],
    /// Friction coefficient of the table (default 0.5: pybullet's default for a URDF link without
    /// a `<contact>` block; unverified in the reference).
    pub friction: f32,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            center_m: [0.0, -0.65, 0.76],
            size_m: [1.0, 0.65, 0.05],
            friction: 0.5,
        }
    }
}

impl TableConfig {
    /// Height of the table top (m).
    pub fn top_z_m(&self) -> f32 {
        self.center_m[2] + 0.5 * self.size_m[2]
    }
}

/// A fixed basket (tray): an open box of thin walls on its floor plate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BasketConfig {
    /// Centre of the basket's floor top face (m; default (0.7, 0, 0.685), the reference
    /// target tray; the second default basket mirrors it to (−0.7, 0, 0.685)).
    pub floor_center_m: [f32; 3],
    /// Inner size along x and y (m; default 0.42 × 0.42: pybullet's `traybox.urdf` scaled by
    /// 0.7 as in the reference, approximately).
    pub inner_size_m: [f32; 2],
    /// Height of the walls above the floor (m; default 0.1).
    pub wall_height_m: f32,
    /// Thickness of the walls and the floor plate (m; default 0.01).
    pub wall_thickness_m: f32,
    /// Friction coefficient (default 0.5, as the table).
    pub friction: f32,
}

impl Default for BasketConfig {
    fn default() -> Self {
        Self {
            floor_center_m: [0.7, 0.0, 0.685],
            inner_size_m: [0.42, 0.42],
            wall_height_m: 0.1,
            wall_thickness_m: 0.01,
            friction: 0.5,
        }
    }
}

impl BasketConfig {
    /// The same basket mirrored across the plane x = 0.
    pub fn mirrored_x(&self) -> Self {
        let [x, y, z] = self.floor_center_m;
        Self {
            floor_center_m: [-x, y, z],
            ..self.clone()
        }
    }

    /// The inside of the basket as an axis-aligned box `(min, max)` (m): from the floor top to
    /// the wall tops, between the walls. A placement succeeds when the object's centre is here.
    pub fn inner_bounds_m(&self) -> ([f32; 3], [f32; 3]) {
        let [x, y, z] = self.floor_center_m;
        let [hx, hy] = [0.5 * self.inner_size_m[0], 0.5 * self.inner_size_m[1]];
        (
            [x - hx, y - hy, z],
            [x + hx, y + hy, z + self.wall_height_m],
        )
    }
}

/// Material and mass rules for dynamic objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectMaterial {
    /// Density of the convex hull (kg/m³; default 400: hulls fill hollow objects — a mug's hull
    /// is ~0.5 l — so a solid-material density would make household objects far too heavy;
    /// 400 gives a mug ~200 g, a 5 cm cube 50 g).
    pub density_kg_m3: f32,
    /// The mass is clamped up to this (kg; default 0.05).
    pub min_mass_kg: f32,
    /// The mass is clamped down to this (kg; default 0.5: the grip holds 2·μ·F = 80 N, and a
    /// cereal-box hull at 400 kg/m³ would weigh 1.4 kg).
    pub max_mass_kg: f32,
    /// Friction coefficient (default 1.0, the reference objects' `lateralFriction`).
    pub friction: f32,
    /// Restitution (default 0; the reference's 0.01 is negligible).
    pub restitution: f32,
    /// Angular velocity damping (1/s; default 0.5): a stand-in for the reference's rolling and
    /// spinning friction (0.002 / 0.001), which rapier lacks — without it a lying bottle rolls
    /// across the table for seconds.
    pub angular_damping: f32,
}

impl Default for ObjectMaterial {
    fn default() -> Self {
        Self {
            density_kg_m3: 400.0,
            min_mass_kg: 0.05,
            max_mass_kg: 0.5,
            friction: 1.0,
            restitution: 0.0,
            angular_damping: 0.5,
        }
    }
}

impl ObjectMaterial {
    /// This material with an object's own mass and friction where it has them (an imported
    /// mesh's `objects.toml`): the mass replaces the density rule and its clamp.
    pub fn with_physics(&self, physics: &lgdm_pointcloud::sidecar::ObjectPhysics) -> Self {
        let mut m = self.clone();
        if let Some(kg) = physics.mass_kg {
            m.min_mass_kg = kg;
            m.max_mass_kg = kg;
        }
        if let Some(mu) = physics.friction {
            m.friction = mu;
        }
        m
    }

    /// Checks every field; the error names the first bad one (prefixed with `prefix`).
    pub(crate) fn validate(&self, prefix: &str) -> Result<(), WorldError> {
        positive(&format!("{prefix}density_kg_m3"), self.density_kg_m3)?;
        positive(&format!("{prefix}min_mass_kg"), self.min_mass_kg)?;
        positive(&format!("{prefix}max_mass_kg"), self.max_mass_kg)?;
        if self.min_mass_kg > self.max_mass_kg {
            return Err(WorldError::InvalidConfig {
                field: format!("{prefix}min_mass_kg"),
                reason: format!(
                    "{} is above max_mass_kg {}",
                    self.min_mass_kg, self.max_mass_kg
                ),
            });
        }
        non_negative(&format!("{prefix}friction"), self.friction)?;
        non_negative(&format!("{prefix}restitution"), self.restitution)?;
        non_negative(&format!("{prefix}angular_damping"), self.angular_damping)?;
        Ok(())
    }
}

/// When [`World::settle`](crate::physics::world::World::settle) calls the scene at rest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SettleConfig {
    /// Every object's linear speed below this (m/s; default 0.005), or asleep.
    pub max_linear_speed_m_s: f32,
    /// Every object's angular speed below this (rad/s; default 0.05), or asleep.
    pub max_angular_speed_rad_s: f32,
    /// For this many consecutive steps (default 12 = 0.05 s).
    pub quiet_steps: u32,
    /// Give up after this many steps (default 1000, the reference `wait_until_all_still` cap).
    pub max_steps: u32,
    /// Warm-start coefficient while settling (default 0.8). Fully warm-started contacts keep
    /// some tall round objects (bottles, vases) wobbling on their rim for seconds; 0.8 lets all
    /// 100 test drops of the procedural library come to rest. Settling is scene preparation, so
    /// the softer solver is used only there; the world's own coefficient is restored after.
    pub warmstart_coefficient: f32,
}

impl Default for SettleConfig {
    fn default() -> Self {
        Self {
            max_linear_speed_m_s: 0.005,
            max_angular_speed_rad_s: 0.05,
            quiet_steps: 12,
            max_steps: 1000,
            warmstart_coefficient: 0.8,
        }
    }
}

/// Every constant of the physics world. Defaults are stated per field; `WorldConfig::default()`
/// is the reference tabletop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorldConfig {
    /// Gravity along world z (m/s²; default −9.81; the reference uses −10).
    pub gravity_z_m_s2: f32,
    /// Time step (s; default 1/240, pybullet's step).
    pub dt_s: f32,
    /// rapier solver iterations (substeps) per step (default 4, rapier's default).
    pub solver_iterations: u32,
    /// Internal PGS iterations per solver iteration (default 4; rapier's default of 1 lets a
    /// squeezed box creep 6–20 mm/s out of the grip).
    pub internal_pgs_iterations: u32,
    /// Natural frequency of contact constraints between two dynamic bodies (Hz; default 480;
    /// rapier's 30 Hz lets 40 N fingers sink 2–4 cm into a 5 cm box, 480 Hz ~0.3 mm).
    pub contact_frequency_hz: f32,
    /// Damping ratio of contact constraints (default 10, rapier's default).
    pub contact_damping_ratio: f32,
    /// Natural frequency of contacts against fixed or kinematic bodies (Hz; default 480; rapier's
    /// default is 60).
    pub static_contact_frequency_hz: f32,
    /// Friction model (default `simplified`, rapier's default).
    pub friction_model: FrictionKind,
    /// Fraction of the previous step's contact and joint impulses the solver starts from
    /// (default 1, rapier's default: static friction in a grip needs it — at 0.8 a squeezed
    /// box creeps ~3 mm/s, at 0 it slides out; see [`SettleConfig::warmstart_coefficient`]).
    pub warmstart_coefficient: f32,
    /// Warm-start joint impulses from the previous step (default true: the stiff finger motors
    /// converge better; rapier's default is false).
    pub warmstart_joints: bool,
    /// Let rapier reuse a pair's contact points while the pair moved less than
    /// `contact_recycle_distance_m` since its last full update (default true, as rapier).
    pub contact_recycling: bool,
    /// How far a pair may move before its contacts are recomputed (m; default 0.001). rapier's
    /// default, 0.05, keeps stale contact anchors over centimetres: a finger that passed beside
    /// a box's top edge during the descent then stops 1 cm short of the box when it closes.
    pub contact_recycle_distance_m: f32,
    /// Bodies closer than this get predictive (speculative) contacts (m; default 0.002; rapier's
    /// default is 0.02). With 2 cm every convex part of a decomposed bowl or mug within 2 cm of
    /// the table gets a speculative contact, and rapier keeps such a body wobbling at 0.5–3 rad/s
    /// for ever; at 5 mm a teapot still wobbles, at 2 mm every library object rests as its
    /// single hull does. Faster bodies then overlap by a few millimetres for a step (an object
    /// released 3 cm above the basket floor lands at 0.8 m/s, 3.2 mm per step) and are pushed
    /// back out: every fixed plate is thicker than that.
    pub prediction_distance_m: f32,
    /// Let bodies at rest fall asleep (default true; a touch or a joint wakes them).
    pub allow_sleep: bool,
    /// The table.
    pub table: TableConfig,
    /// The baskets (default two: the reference target tray at (0.7, 0, 0.685) and its mirror at
    /// (−0.7, 0, 0.685)).
    pub baskets: Vec<BasketConfig>,
    /// A fixed floor plane at z = 0 (default true) so an object knocked off the table comes to
    /// rest instead of falling forever.
    pub floor: bool,
    /// Material of spawned objects.
    pub object: ObjectMaterial,
    /// A flat hull face with more vertices keeps only this many of them, chosen by
    /// farthest-point sampling (default 12). With warm-started contacts rapier rocks an upright
    /// cylinder whose base is a 32-gon until it topples (the four contact points it keeps of a
    /// many-sided face change every step); 8–12-gon bases rest. Only the big flat faces (the
    /// base and top of a can, the sides of a box never) lose vertices, so the hull's width
    /// elsewhere is kept.
    pub max_face_vertices: u32,
    /// When the scene counts as settled.
    pub settle: SettleConfig,
}

impl Default for WorldConfig {
    fn default() -> Self {
        let basket = BasketConfig::default();
        Self {
            gravity_z_m_s2: -9.81,
            dt_s: 1.0 / 240.0,
            solver_iterations: 4,
            internal_pgs_iterations: 4,
            contact_frequency_hz: 480.0,
            contact_damping_ratio: 10.0,
            static_contact_frequency_hz: 60.0,
            friction_model: FrictionKind::Simplified,
            warmstart_coefficient: 1.0,
            warmstart_joints: true,
            contact_recycling: true,
            contact_recycle_distance_m: 0.001,
            prediction_distance_m: 0.002,
            allow_sleep: true,
            table: TableConfig::default(),
            baskets: vec![basket.clone(), basket.mirrored_x()],
            floor: true,
            object: ObjectMaterial::default(),
            max_face_vertices: 12,
            settle: SettleConfig::default(),
        }
    }
}

pub(crate) fn finite(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} is not finite"),
        })
    }
}

fn positive(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} must be positive and finite"),
        })
    }
}

fn non_negative(field: &str, value: f32) -> Result<(), WorldError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: format!("{value} must be non-negative and finite"),
        })
    }
}

fn at_least_one(field: &str, value: u32) -> Result<(), WorldError> {
    if value >= 1 {
        Ok(())
    } else {
        Err(WorldError::InvalidConfig {
            field: field.to_string(),
            reason: "must be at least 1".into(),
        })
    }
}

impl WorldConfig {
    /// Checks every field; the error names the first bad one (e.g. `table.size_m[2]`).
    pub fn validate(&self) -> Result<(), WorldError> {
        finite("gravity_z_m_s2", self.gravity_z_m_s2)?;
        non_negative(
            "contact_recycle_distance_m",
            self.contact_recycle_distance_m,
        )?;
        positive("prediction_distance_m", self.prediction_distance_m)?;
        positive("dt_s", self.dt_s)?;
        if self.dt_s > 0.05 {
            return Err(WorldError::InvalidConfig {
                field: "dt_s".into(),
                reason: format!("{} s is longer than 0.05 s", self.dt_s),
            });
        }
        at_least_one("solver_iterations", self.solver_iterations)?;
        at_least_one("internal_pgs_iterations", self.internal_pgs_iterations)?;
        positive("contact_frequency_hz", self.contact_frequency_hz)?;
        non_negative("contact_damping_ratio", self.contact_damping_ratio)?;
        positive(
            "static_contact_frequency_hz",
            self.static_contact_frequency_hz,
        )?;
        for (i, v) in self.table.center_m.iter().enumerate() {
            finite(&format!("table.center_m[{i}]"), *v)?;
        }
        for (i, v) in self.table.size_m.iter().enumerate() {
            positive(&format!("table.size_m[{i}]"), *v)?;
        }
        non_negative("table.friction", self.table.friction)?;
        for (b, basket) in self.baskets.iter().enumerate() {
            for (i, v) in basket.floor_center_m.iter().enumerate() {
                finite(&format!("baskets[{b}].floor_center_m[{i}]"), *v)?;
            }
            for (i, v) in basket.inner_size_m.iter().enumerate() {
                positive(&format!("baskets[{b}].inner_size_m[{i}]"), *v)?;
            }
            positive(&format!("baskets[{b}].wall_height_m"), basket.wall_height_m)?;
            positive(
                &format!("baskets[{b}].wall_thickness_m"),
                basket.wall_thickness_m,
            )?;
            non_negative(&format!("baskets[{b}].friction"), basket.friction)?;
        }
        self.object.validate("object.")?;
        positive(
            "settle.max_linear_speed_m_s",
            self.settle.max_linear_speed_m_s,
        )?;
        positive(
            "settle.max_angular_speed_rad_s",
            self.settle.max_angular_speed_rad_s,
        )?;
        at_least_one("settle.quiet_steps", self.settle.quiet_steps)?;
        if self.max_face_vertices < 3 {
            return Err(WorldError::InvalidConfig {
                field: "max_face_vertices".into(),
                reason: format!("{} is below 3", self.max_face_vertices),
            });
        }
        at_least_one("settle.max_steps", self.settle.max_steps)?;
        for (field, value) in [
            ("warmstart_coefficient", self.warmstart_coefficient),
            (
                "settle.warmstart_coefficient",
                self.settle.warmstart_coefficient,
            ),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(WorldError::InvalidConfig {
                    field: field.into(),
                    reason: format!("{value} is outside [0, 1]"),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::world::World;

    #[test]
    fn default_config_is_valid_and_reference_sized() {
        let cfg = WorldConfig::default();
        cfg.validate().unwrap();
        assert!((cfg.table.top_z_m() - 0.785).abs() < 1e-6);
        assert_eq!(cfg.baskets.len(), 2);
        assert_eq!(cfg.baskets[1].floor_center_m, [-0.7, 0.0, 0.685]);
    }

    #[test]
    fn config_validation_names_the_field() {
        let mut cfg = WorldConfig::default();
        cfg.table.size_m[2] = 0.0;
        let err = cfg.validate().unwrap_err();
        assert!(
            matches!(&err, WorldError::InvalidConfig { field, .. } if field == "table.size_m[2]"),
            "{err}"
        );
        let cfg = WorldConfig {
            dt_s: f32::NAN,
            ..WorldConfig::default()
        };
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "dt_s"
        ));
        let mut cfg = WorldConfig::default();
        cfg.baskets[1].wall_height_m = -0.1;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "baskets[1].wall_height_m"
        ));
        let mut cfg = WorldConfig::default();
        cfg.object.min_mass_kg = 1.0;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "object.min_mass_kg"
        ));
        let mut cfg = WorldConfig::default();
        cfg.settle.max_steps = 0;
        assert!(matches!(
            cfg.validate(),
            Err(WorldError::InvalidConfig { field, .. }) if field == "settle.max_steps"
        ));
        let cfg = WorldConfig {
            internal_pgs_iterations: 0,
            ..WorldConfig::default()
        };
        assert!(World::new(cfg).is_err());
    }

    #[test]
    fn config_serde_roundtrip_and_defaults() {
        let cfg = WorldConfig::default();
        let json = serde_json::to_string(&cfg).unwrap();
        assert_eq!(serde_json::from_str::<WorldConfig>(&json).unwrap(), cfg);
        assert_eq!(serde_json::from_str::<WorldConfig>("{}").unwrap(), cfg);
        assert!(serde_json::from_str::<WorldConfig>(r#"{"dt": 0.1}"#).is_err());
    }
}
