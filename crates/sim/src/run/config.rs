//! Every constant of a sim run in one serde struct, [`SimConfig`]: the world, the robot, the
//! cameras, the attempt's motions and judging, how tables are set, the objects' colliders. Each
//! part's defaults are its own; [`crate::run::spec`] checks the whole (`SimConfig::validate`).
//!
//! ```
//! use lgdm_sim::run::config::SimConfig;
//! let config = SimConfig::default();
//! assert_eq!(config.grasp_spec().max_opening_m, config.robot.gripper.stroke_m);
//! ```

use std::path::Path;

use lgdm_pointcloud::grasp::GraspSpec;
use serde::{Deserialize, Serialize};

use crate::grasping::attempt::AttemptConfig;
use crate::grasping::source::ProposalCheck;
use crate::perception::camera::{CameraConfig, ObjectDrawing};
use crate::physics::config::WorldConfig;
use crate::physics::shapes::{ObjectShape, ShapeConfig};
use crate::robot::RobotConfig;
use crate::robot::gripper::{GripperConfig, GripperModel};
use crate::tasks::scenario::ScenarioConfig;

/// A constant the robot commands set by a word (`--gripper 2f-85`, Python's `gripper="2f-85"`):
/// the one spelling of each value, which the CLI's options and `lgdm.sim`'s keywords both parse.
pub trait OptionValue: Copy + Send + Sync + 'static {
    /// The option's name (`gripper`).
    const OPTION: &'static str;
    /// Every value, in the order help lists them.
    const ALL: &'static [Self];
    /// The value's word.
    fn word(self) -> &'static str;
    /// One line on the value (the CLI's help).
    fn help(self) -> &'static str;
    /// The value named `word`; the error names the option and lists the known words.
    fn parse(word: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|v| v.word() == word)
            .ok_or_else(|| {
                let known: Vec<_> = Self::ALL.iter().map(|v| v.word()).collect();
                format!(
                    "{}: unknown `{word}` (known: {})",
                    Self::OPTION,
                    known.join(", ")
                )
            })
    }
}

impl OptionValue for GripperModel {
    const OPTION: &'static str = "gripper";
    const ALL: &'static [Self] = &GripperModel::ALL;
    fn word(self) -> &'static str {
        self.name()
    }
    fn help(self) -> &'static str {
        match self {
            GripperModel::Robotiq2F85 => "Robotiq 2F-85: 85 mm stroke",
            GripperModel::Robotiq2F140 => {
                "Robotiq 2F-140: 140 mm stroke, longer fingers (the paper's pybullet robot's)"
            }
        }
    }
}

impl OptionValue for ObjectDrawing {
    const OPTION: &'static str = "draw";
    const ALL: &'static [Self] = &[ObjectDrawing::Mesh, ObjectDrawing::Collider];
    fn word(self) -> &'static str {
        match self {
            ObjectDrawing::Mesh => "mesh",
            ObjectDrawing::Collider => "collider",
        }
    }
    fn help(self) -> &'static str {
        match self {
            ObjectDrawing::Mesh => {
                "The object's mesh, as in the dataset (the collider only approximates it)"
            }
            ObjectDrawing::Collider => {
                "The physics collider in the mesh's colours (default): the camera sees what the \
                 fingers meet"
            }
        }
    }
}

impl OptionValue for ProposalCheck {
    const OPTION: &'static str = "proposal-check";
    const ALL: &'static [Self] = &[
        ProposalCheck::Contacts,
        ProposalCheck::Antipodal,
        ProposalCheck::Refine,
        ProposalCheck::RefineFirst,
        ProposalCheck::RefineRanked,
    ];
    fn word(self) -> &'static str {
        ProposalCheck::word(self)
    }
    fn help(self) -> &'static str {
        match self {
            ProposalCheck::Contacts => {
                "Only the planner's check that both pads close on something (default)"
            }
            ProposalCheck::Antipodal => {
                "Also the analytic source's test at each proposal's centre and axis (friction \
                 cone, finger lanes, palm); a proposal that passes is tried as proposed"
            }
            ProposalCheck::Refine => {
                "As antipodal, and each proposal that passes is moved to its contacts' \
                 midpoint, squared to the walls and opened to their distance"
            }
            ProposalCheck::RefineFirst => {
                "As refine, but the refused proposals follow the refined ones as proposed \
                 instead of being dropped"
            }
            ProposalCheck::RefineRanked => {
                "As refine-first, but the refined ones are tried in the analytic source's \
                 order of quality where they settled (safe first), not the proposals' order"
            }
        }
    }
}

impl OptionValue for ObjectShape {
    const OPTION: &'static str = "shapes";
    const ALL: &'static [Self] = &[ObjectShape::Hull, ObjectShape::Decomposition];
    fn word(self) -> &'static str {
        match self {
            ObjectShape::Hull => "hull",
            ObjectShape::Decomposition => "decomposition",
        }
    }
    fn help(self) -> &'static str {
        match self {
            ObjectShape::Hull => "Each object's convex hull: openings and handles are filled",
            ObjectShape::Decomposition => {
                "A convex decomposition where the mesh is open (default; VHACD, 0.1–0.5 s per \
                 object once): openings stay open"
            }
        }
    }
}

/// What the robot commands' options (`--gripper`, `--draw`, `--shapes`) set on top of a config
/// file ([`SimConfig::resolve`]); `None` leaves the file's (or the default) value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ConfigOverrides {
    /// The gripper preset.
    pub gripper: Option<GripperModel>,
    /// What the cameras draw.
    pub draw: Option<ObjectDrawing>,
    /// The objects' collider shapes.
    pub shapes: Option<ObjectShape>,
    /// How grasp proposals are checked before planning.
    pub proposal_check: Option<ProposalCheck>,
}

/// Every constant of a sim run. Defaults are each part's.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// The physics world.
    pub world: WorldConfig,
    /// The robot (arm and gripper).
    pub robot: RobotConfig,
    /// Cameras, crop and segmentation.
    pub cameras: CameraConfig,
    /// Motions and judging of one attempt.
    pub attempt: AttemptConfig,
    /// How tables are set and rounds end.
    pub scenario: ScenarioConfig,
    /// Objects' collider shapes (default: a convex decomposition of each mesh).
    pub shapes: ShapeConfig,
}

impl SimConfig {
    /// Every field as TOML (what a run directory's [`crate::run::run_dir::CONFIG_FILE`] holds).
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }

    /// A config from TOML text: fields left out take their defaults, an unknown field is an
    /// error naming it and where it is. Not validated here ([`SimConfig::validate`]).
    pub fn from_toml(text: &str) -> Result<SimConfig, String> {
        toml::from_str(text).map_err(|e| e.to_string().trim_end().to_string())
    }

    /// The run's constants as the robot commands take them: `file`'s config (else the
    /// defaults) with `overrides` on top — options that set constants are applied over the
    /// file, never silently under it — checked whole. Errors name the file and the field.
    pub fn resolve(file: Option<&Path>, overrides: &ConfigOverrides) -> Result<SimConfig, String> {
        let mut config = match file {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| format!("{}: {e}", path.display()))?;
                SimConfig::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()))?
            }
            None => SimConfig::default(),
        };
        if let Some(gripper) = overrides.gripper {
            config.robot.gripper = GripperConfig::preset(gripper);
        }
        if let Some(draw) = overrides.draw {
            config.cameras.draw = draw;
        }
        if let Some(shape) = overrides.shapes {
            config.shapes.shape = shape;
        }
        if let Some(check) = overrides.proposal_check {
            config.attempt.proposal_check = Some(check);
        }
        if let Some(path) = file {
            config
                .validate()
                .map_err(|e| format!("{}: {e}", path.display()))?;
        }
        Ok(config)
    }

    /// The gripper as grasp sources see it: the robot's stroke and finger width, the dataset's
    /// finger reach, clearance and friction.
    pub fn grasp_spec(&self) -> GraspSpec {
        GraspSpec {
            max_opening_m: self.robot.gripper.stroke_m,
            finger_width_m: self.robot.gripper.finger_width_m,
            ..GraspSpec::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_whole_config_round_trips_through_toml() {
        let mut c = SimConfig::default();
        c.robot.gripper.stroke_m = 0.14;
        let text = c.to_toml().unwrap();
        assert_eq!(SimConfig::from_toml(&text).unwrap(), c);
        // Left out: the defaults; unknown: named.
        assert_eq!(SimConfig::from_toml("").unwrap(), SimConfig::default());
        let e = SimConfig::from_toml("[robot.gripper]\nstroke = 0.1\n").unwrap_err();
        assert!(e.contains("stroke"), "{e}");
    }
}
