//! Where a job's objects come from ([`ObjectSource`]: the procedural objects or a folder of
//! meshes) and the library it loads ([`ObjectLibrary`]), for the robot's jobs and for
//! `lgdm sim grasp-data`.

use std::path::PathBuf;

use lgdm_pointcloud::import::{ImportReport, MeshUnits, load_mesh_library};
use lgdm_pointcloud::objects::{CATEGORIES, ObjectModel, procedural_library};
use serde::{Deserialize, Serialize};

use crate::run::error::{SimError, setting};

/// Where a job's objects come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectSource {
    /// The procedural objects: `instances` per category, built from `seed`.
    Procedural {
        /// Instances per category (at least 1).
        instances: usize,
        /// The generator's seed (0: the embedded dataset's).
        seed: u64,
    },
    /// The meshes of `dir` in the `gen-dataset` layout (`DIR/<category>/<instance>.{obj,stl,ply}`),
    /// in `units` (guessed from the size where not given).
    Meshes {
        /// The folder.
        dir: PathBuf,
        /// Their units.
        units: MeshUnits,
    },
}

impl Default for ObjectSource {
    /// The procedural objects of the embedded dataset: 5 per category, seed 0.
    fn default() -> Self {
        Self::Procedural {
            instances: 5,
            seed: 0,
        }
    }
}

/// The most procedural instances per category a job may build (10 categories: 1,000 objects,
/// ~50 MB of meshes).
pub const MAX_INSTANCES: usize = 100;

/// A job's objects.
#[derive(Debug, Clone)]
pub struct ObjectLibrary {
    /// The objects.
    pub objects: Vec<ObjectModel>,
    /// Where they came from, for the record (`procedural`, `meshes DIR`).
    pub label: String,
    /// Imported meshes: each file's unit and size (the binary prints them).
    pub imported: Vec<ImportReport>,
}

impl ObjectSource {
    /// Builds or imports the objects.
    pub fn load(&self) -> Result<ObjectLibrary, SimError> {
        match self {
            Self::Procedural { instances, seed } => {
                if *instances == 0 {
                    return Err(setting(
                        "instances",
                        0,
                        "at least one instance per category is needed",
                    ));
                }
                if *instances > MAX_INSTANCES {
                    return Err(setting(
                        "instances",
                        instances,
                        format!("at most {MAX_INSTANCES} instances per category"),
                    ));
                }
                let objects = procedural_library(&CATEGORIES, *instances, *seed)
                    .map_err(|e| SimError::Objects(e.to_string()))?;
                Ok(ObjectLibrary {
                    objects,
                    label: "procedural".into(),
                    imported: Vec::new(),
                })
            }
            Self::Meshes { dir, units } => {
                let imported = load_mesh_library(dir, units)
                    .map_err(|e| SimError::Objects(format!("--meshes {}: {e}", dir.display())))?;
                let reports = imported.iter().map(|i| i.report.clone()).collect();
                Ok(ObjectLibrary {
                    objects: imported.into_iter().map(|i| i.object).collect(),
                    label: format!("meshes {}", dir.display()),
                    imported: reports,
                })
            }
        }
    }
}
