//! `objects.toml`: what a mesh file cannot say, beside the meshes it describes.
//!
//! A mesh library (`<dir>/<category>/<instance>.{obj,stl,ply}`) may hold an [`SIDECAR_FILE`] in
//! `<dir>` with settings for every file (`[all]`) and for single files (`[files."<category>/
//! <file>"]`, which take precedence field by field):
//!
//! ```toml
//! [all]
//! unit = "m"
//!
//! [files."mustard_bottle/mustard_bottle_01.stl"]
//! rest_rpy_deg = [90.0, 0.0, 0.0]   # lying on its side
//! colour = "#e0b81c"
//! mass_kg = 0.603
//! friction = 0.8
//! ```
//!
//! - `unit`: `mm`, `cm` or `m` (a `--units` flag wins over it);
//! - `rest_rpy_deg`: the rest pose, as roll, pitch and yaw in degrees about the file's x, y
//!   and z axes (applied in that order) before the mesh is centred and set on the table;
//! - `colour`: `#rrggbb` for every triangle (STL files have no colour; the cameras and the
//!   autoencoder see it);
//! - `mass_kg` (0.001–50) and `friction` (0–10): the simulator's body, instead of the mass the
//!   hull's volume gives and the default friction.
//!
//! Every value is checked with an error naming the file and the field; a file entry naming no
//! mesh of the library is an error too.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::import::LengthUnit;
use crate::math::{Pose, rotation_axis_angle};

/// The sidecar's file name, in the meshes directory.
pub const SIDECAR_FILE: &str = "objects.toml";
/// Heaviest `mass_kg` accepted.
pub const MAX_MASS_KG: f32 = 50.0;
/// Lightest `mass_kg` accepted.
pub const MIN_MASS_KG: f32 = 0.001;
/// Largest `friction` accepted.
pub const MAX_FRICTION: f32 = 10.0;

/// Settings of one mesh file (or, under `[all]`, of every file); each may be left out.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectProps {
    /// Unit of the file's coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<LengthUnit>,
    /// Rest pose: roll, pitch, yaw (degrees) about the file's x, y, z axes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rest_rpy_deg: Option<[f32; 3]>,
    /// Colour of every triangle, `#rrggbb`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<String>,
    /// Mass of the simulated body (kg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f32>,
    /// Friction coefficient of the simulated body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f32>,
}

impl ObjectProps {
    /// `self`, with `base`'s value wherever `self` has none.
    pub fn or(&self, base: &ObjectProps) -> ObjectProps {
        ObjectProps {
            unit: self.unit.or(base.unit),
            rest_rpy_deg: self.rest_rpy_deg.or(base.rest_rpy_deg),
            colour: self.colour.clone().or_else(|| base.colour.clone()),
            mass_kg: self.mass_kg.or(base.mass_kg),
            friction: self.friction.or(base.friction),
        }
    }

    /// Whether nothing is set.
    pub fn is_empty(&self) -> bool {
        *self == ObjectProps::default()
    }

    /// Checks every field; the error names the field (prefixed with `at`).
    fn check(&self, at: &str) -> Result<(), String> {
        if let Some(rpy) = self.rest_rpy_deg
            && let Some(v) = rpy.iter().find(|v| !(v.is_finite() && v.abs() <= 360.0))
        {
            return Err(format!(
                "{at}rest_rpy_deg: {v} is not an angle in degrees (-360 to 360)"
            ));
        }
        if let Some(c) = &self.colour {
            parse_colour(c).map_err(|e| format!("{at}colour: {e}"))?;
        }
        if let Some(m) = self.mass_kg
            && !(m.is_finite() && (MIN_MASS_KG..=MAX_MASS_KG).contains(&m))
        {
            return Err(format!(
                "{at}mass_kg: {m} is not a mass from {MIN_MASS_KG} to {MAX_MASS_KG} kg"
            ));
        }
        if let Some(f) = self.friction
            && !(f.is_finite() && (0.0..=MAX_FRICTION).contains(&f))
        {
            return Err(format!(
                "{at}friction: {f} is not a friction coefficient from 0 to {MAX_FRICTION}"
            ));
        }
        Ok(())
    }

    /// The colour as RGB, when set (checked by [`Sidecar::read`]).
    pub fn rgb(&self) -> Option<[u8; 3]> {
        self.colour.as_deref().and_then(|c| parse_colour(c).ok())
    }

    /// The rest pose's rotation (`Rz(yaw)·Ry(pitch)·Rx(roll)`), when set.
    pub fn rest_rotation(&self) -> Option<Pose> {
        self.rest_rpy_deg.map(|[r, p, y]| {
            rotation_axis_angle([0.0, 0.0, 1.0], y.to_radians())
                * rotation_axis_angle([0.0, 1.0, 0.0], p.to_radians())
                * rotation_axis_angle([1.0, 0.0, 0.0], r.to_radians())
        })
    }

    /// What the simulator's body takes from these settings.
    pub fn physics(&self) -> ObjectPhysics {
        ObjectPhysics {
            mass_kg: self.mass_kg,
            friction: self.friction,
        }
    }
}

/// A simulated body's mass and friction, where a sidecar gives them (else the simulator's
/// material rules apply).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectPhysics {
    /// Mass (kg).
    pub mass_kg: Option<f32>,
    /// Friction coefficient.
    pub friction: Option<f32>,
}

/// `#rrggbb` as RGB.
pub fn parse_colour(s: &str) -> Result<[u8; 3], String> {
    let hex = s
        .strip_prefix('#')
        .filter(|h| h.len() == 6 && h.chars().all(|c| c.is_ascii_hexdigit()))
        .ok_or_else(|| format!("`{s}` is not a colour as #rrggbb (e.g. #e0b81c)"))?;
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).expect("checked hex digits");
    Ok([byte(0), byte(2), byte(4)])
}

/// `rgb` as `#rrggbb`.
pub fn format_colour([r, g, b]: [u8; 3]) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// The contents of an `objects.toml`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sidecar {
    /// Settings of every file.
    #[serde(default, skip_serializing_if = "ObjectProps::is_empty")]
    pub all: ObjectProps,
    /// Settings of single files, by `<category>/<file>` relative to the meshes directory.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub files: BTreeMap<String, ObjectProps>,
}

/// Why a sidecar cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {reason}", path.display())]
pub struct SidecarError {
    /// The sidecar file.
    pub path: PathBuf,
    /// What is wrong, naming the field.
    pub reason: String,
}

impl Sidecar {
    /// The sidecar of the meshes directory `dir` ([`SIDECAR_FILE`]), empty when there is none;
    /// every value checked.
    pub fn read(dir: &Path) -> Result<Sidecar, SidecarError> {
        let path = dir.join(SIDECAR_FILE);
        let err = |reason: String| SidecarError {
            path: path.clone(),
            reason,
        };
        let text = match std::fs::read(&path) {
            Ok(bytes) => String::from_utf8(bytes).map_err(|_| err("not UTF-8 text".into()))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Sidecar::default()),
            Err(e) => return Err(err(format!("cannot read: {e}"))),
        };
        let sidecar: Sidecar =
            toml::from_str(&text).map_err(|e| err(e.to_string().trim_end().to_string()))?;
        sidecar.check().map_err(err)?;
        Ok(sidecar)
    }

    /// Checks every value and file name; the error names the field.
    pub fn check(&self) -> Result<(), String> {
        self.all.check("all.")?;
        for (file, props) in &self.files {
            if !crate::import::is_file_key(file) {
                return Err(format!(
                    "files.\"{file}\": name the file as <category>/<file> relative to the \
                     meshes directory (e.g. \"mug/mug_01.stl\")"
                ));
            }
            props.check(&format!("files.\"{file}\"."))?;
        }
        Ok(())
    }

    /// The settings of `file` (`<category>/<file>`): its own, then `[all]`'s.
    pub fn props(&self, file: &str) -> ObjectProps {
        match self.files.get(file) {
            Some(p) => p.or(&self.all),
            None => self.all.clone(),
        }
    }

    /// The sidecar as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a sidecar serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_round_trip_and_bad_ones_are_named() {
        assert_eq!(parse_colour("#e0b81c"), Ok([0xe0, 0xb8, 0x1c]));
        assert_eq!(format_colour([0xe0, 0xb8, 0x1c]), "#e0b81c");
        for bad in ["e0b81c", "#e0b81", "#e0b81cc", "#g0b81c", "", "#ÿÿÿ"] {
            assert!(parse_colour(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn file_settings_take_precedence_field_by_field() {
        let s: Sidecar = toml::from_str(
            "[all]\nunit = \"m\"\nfriction = 0.5\n[files.\"a/b.stl\"]\nfriction = 0.9\n",
        )
        .unwrap();
        s.check().unwrap();
        let p = s.props("a/b.stl");
        assert_eq!((p.unit, p.friction), (Some(LengthUnit::Metre), Some(0.9)));
        let q = s.props("a/c.stl");
        assert_eq!((q.unit, q.friction), (Some(LengthUnit::Metre), Some(0.5)));
    }

    #[test]
    fn a_quarter_turn_of_pitch_lays_z_along_x() {
        let p = ObjectProps {
            rest_rpy_deg: Some([0.0, 90.0, 0.0]),
            ..ObjectProps::default()
        };
        let r = p.rest_rotation().unwrap();
        let v = crate::math::rotate_vector(&r, [0.0, 0.0, 1.0]);
        assert!((v[0] - 1.0).abs() < 1e-6 && v[2].abs() < 1e-6, "{v:?}");
    }
}
