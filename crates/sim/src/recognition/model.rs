//! The model a pick-and-place run starts from and the one it leaves: a dual-memory checkpoint
//! ([`MODEL_FILE`] in a run directory, or `lgdm train`'s `model-trial<t>.lgdm`) and the record
//! beside it that says what its ids mean and which encoder made its features ([`ModelRecord`]:
//! a pick-place run's [`MODEL_LABELS_FILE`], or `lgdm train`'s `metrics.json`, whose fields it
//! shares). [`StartModel::load`] checks a checkpoint against the encoder a run recognises with
//! — its name and feature dimension — before the encoder (and torch) is loaded.
//!
//! ```no_run
//! use lgdm_sim::recognition::model::StartModel;
//! let start = StartModel::load("runs/ni/model-trial0.lgdm".as_ref(), "good", 675).unwrap();
//! println!("{} categories known", start.labels.map_or(0, |l| l.categories.len()));
//! ```

use std::path::{Path, PathBuf};

use lgdm_gdm::Gdm;
use serde::{Deserialize, Serialize};

use crate::recognition::error::RecognitionError;
use crate::recognition::labels::Labels;

/// The model a pick-and-place run learnt, as a dual-memory checkpoint (`lgdm eval --model`,
/// `lgdm.GDM.load`, `--model` of another run).
pub const MODEL_FILE: &str = "model.lgdm";

/// Beside [`MODEL_FILE`]: its encoder and label names ([`ModelRecord`]).
pub const MODEL_LABELS_FILE: &str = "model.json";

/// What a model's ids mean and which encoder made its features: `{"encoder", "categories",
/// "instances"}`, the fields of `lgdm train`'s `metrics.json` that say so.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModelRecord {
    /// The encoder (`good`, `ae`).
    pub encoder: String,
    /// Category names by id.
    pub categories: Vec<String>,
    /// Instance names by id.
    #[serde(default)]
    pub instances: Vec<String>,
}

impl ModelRecord {
    /// The record of a model whose ids mean `labels`, made with `encoder`.
    pub fn new(encoder: &str, labels: &Labels) -> Self {
        Self {
            encoder: encoder.to_string(),
            categories: labels.categories.clone(),
            instances: labels.instances.clone(),
        }
    }

    /// Pretty JSON with a trailing newline (what [`MODEL_LABELS_FILE`] holds).
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("a model record serialises");
        s.push('\n');
        s
    }

    /// The record beside the checkpoint `model`: `metrics.json` (`lgdm train`) or
    /// [`MODEL_LABELS_FILE`] (pick-place), with its path; `None` when there is neither.
    pub fn beside(model: &Path) -> Result<Option<(PathBuf, ModelRecord)>, ModelError> {
        let dir = model.parent().unwrap_or(Path::new("."));
        for name in [
            lgdm_gdm::experiment::run_dir::METRICS_FILE,
            MODEL_LABELS_FILE,
        ] {
            let path = dir.join(name);
            if let Ok(text) = std::fs::read_to_string(&path) {
                let record = serde_json::from_str(&text).map_err(|source| ModelError::Record {
                    path: path.clone(),
                    source,
                })?;
                return Ok(Some((path, record)));
            }
        }
        Ok(None)
    }
}

/// Why a model cannot start a run.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The checkpoint cannot be read.
    #[error("reading the model {}", path.display())]
    Load {
        /// The checkpoint.
        path: PathBuf,
        /// Why.
        source: lgdm_gdm::CheckpointError,
    },
    /// The record beside it cannot be read.
    #[error("reading the model's record {} (encoder and label names)", path.display())]
    Record {
        /// The record.
        path: PathBuf,
        /// Why.
        source: serde_json::Error,
    },
    /// It was trained with another encoder.
    #[error(
        "model {}: the model was trained with the `{trained}` encoder ({}), this run recognises \
         with `{wanted}`: pass --encoder {trained} or a model trained on {wanted} features",
        path.display(), record.display()
    )]
    Encoder {
        /// The checkpoint.
        path: PathBuf,
        /// The record that names its encoder.
        record: PathBuf,
        /// Its encoder.
        trained: String,
        /// The run's.
        wanted: String,
    },
    /// Its record names fewer categories or instances than the model has learnt.
    #[error(
        "model {}: its record {} names {named} {what}, but the model has learnt {learnt}: the \
         record is not this model's (a pick-place run writes both; lgdm train's metrics.json \
         names them)",
        path.display(), record.display()
    )]
    Names {
        /// The checkpoint.
        path: PathBuf,
        /// The record.
        record: PathBuf,
        /// `categories` or `instances`.
        what: &'static str,
        /// Names in the record.
        named: usize,
        /// Ids the model uses (the largest + 1).
        learnt: usize,
    },
    /// Its features have another dimension than the encoder's.
    #[error("model {}", path.display())]
    Dimension {
        /// The checkpoint.
        path: PathBuf,
        /// The mismatch.
        source: RecognitionError,
    },
}

/// A checkpoint to start from, checked against the run's encoder.
#[derive(Debug)]
pub struct StartModel {
    /// Where it came from.
    pub path: PathBuf,
    /// The dual memory.
    pub gdm: Gdm,
    /// What its ids mean (none: no record beside it; the ids are then taken as the dataset
    /// ids of the object library).
    pub labels: Option<Labels>,
}

impl StartModel {
    /// Loads `path` and checks it against the encoder `encoder` of `dim` values per feature:
    /// the encoder its record names and the model's feature dimension.
    pub fn load(path: &Path, encoder: &str, dim: usize) -> Result<StartModel, ModelError> {
        let gdm = Gdm::load(path).map_err(|source| ModelError::Load {
            path: path.to_path_buf(),
            source,
        })?;
        let labels = match ModelRecord::beside(path)? {
            Some((record_path, record)) => {
                if record.encoder != encoder {
                    return Err(ModelError::Encoder {
                        path: path.to_path_buf(),
                        record: record_path,
                        trained: record.encoder,
                        wanted: encoder.to_string(),
                    });
                }
                let (categories, instances) = label_ids_used(&gdm);
                for (what, named, learnt) in [
                    ("categories", record.categories.len(), categories),
                    ("instances", record.instances.len(), instances),
                ] {
                    if named < learnt {
                        return Err(ModelError::Names {
                            path: path.to_path_buf(),
                            record: record_path,
                            what,
                            named,
                            learnt,
                        });
                    }
                }
                Some(Labels {
                    categories: record.categories,
                    instances: record.instances,
                })
            }
            None => None,
        };
        if gdm.dim() != dim {
            return Err(ModelError::Dimension {
                path: path.to_path_buf(),
                source: RecognitionError::Dimension {
                    model: gdm.dim(),
                    name: encoder.to_string(),
                    encoder: dim,
                },
            });
        }
        Ok(StartModel {
            path: path.to_path_buf(),
            gdm,
            labels,
        })
    }
}

/// How many category and instance ids `gdm` uses: the largest label of any node + 1 (0 for an
/// unlabelled model).
fn label_ids_used(gdm: &Gdm) -> (usize, usize) {
    let em = gdm.episodic();
    let sm = gdm.semantic();
    let next = |id: Option<u32>| id.map_or(0, |i| i as usize + 1);
    let categories = (0..em.len())
        .map(|j| next(em.category_of(j)))
        .chain((0..sm.len()).map(|j| next(sm.category_of(j))))
        .max()
        .unwrap_or(0);
    let instances = (0..em.len())
        .map(|j| next(em.instance_of(j)))
        .max()
        .unwrap_or(0);
    (categories, instances)
}
