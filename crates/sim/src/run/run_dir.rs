//! A sim run directory, owned the way `lgdm train --out` owns its own: a new or empty
//! directory, or with `force` one that holds only a previous sim run's files (the ownership
//! policy of [`lgdm_base::fs::claim`]); locked while the run writes; every file written
//! atomically. It holds [`RESULTS_FILE`], [`SUMMARY_FILE`], with recognition [`MODEL_FILE`] and
//! [`MODEL_LABELS_FILE`], with recording [`ROUNDS_DIR`]`/round-NNNN.{mcap,png}`, and the
//! plots (`*.png`, [`crate::run::plots`]).
//!
//! ```
//! use lgdm_sim::run::run_dir::SimRunDir;
//! let tmp = tempfile::tempdir().unwrap();
//! let dir = SimRunDir::create(&tmp.path().join("run"), false).unwrap();
//! dir.write_file("summary.txt", b"nothing yet\n").unwrap();
//! drop(dir);
//! // A previous run is replaced only with force.
//! assert!(SimRunDir::create(&tmp.path().join("run"), false).is_err());
//! assert!(SimRunDir::create(&tmp.path().join("run"), true).is_ok());
//! ```

use std::path::{Path, PathBuf};

use lgdm_base::fs::{DirLock, Entry, Ownership};
use lgdm_gdm::Gdm;
use serde::{Deserialize, Serialize};

use crate::recognition::labels::Labels;
use crate::recognition::model::{MODEL_FILE, MODEL_LABELS_FILE, ModelRecord};
use crate::recognition::recognizer::Recognizer;
use crate::run::error::SimError;
use crate::run::record::{RecordError, RoundRecording, RoundSink};
use crate::run::report::summary_text;
use crate::run::results::{RESULTS_FILE, RunResults};
use crate::run::state::RunState;

/// The run's summary as text (the binary prints the same).
pub const SUMMARY_FILE: &str = "summary.txt";

/// The folder of a run directory that holds the recorded rounds.
pub const ROUNDS_DIR: &str = "rounds";

/// The job a run directory holds, written before the first round ([`crate::run::job::JobRecord`]):
/// what `resume` plays again.
pub const JOB_FILE: &str = "job.json";

/// Every constant the run used ([`crate::run::config::SimConfig`] as TOML), written with the job:
/// `--config RUN_DIR/sim.toml` runs with the same world, robot, cameras and attempts.
pub const CONFIG_FILE: &str = "sim.toml";

/// Where an unfinished run is: written after every round, removed when the run is done
/// ([`Checkpoint`]).
pub const PROGRESS_FILE: &str = "progress.json";

/// The folder of the model an unfinished run had learnt by its last finished round.
pub const PROGRESS_DIR: &str = "progress";

/// What [`PROGRESS_FILE`] holds: the run's state after its finished rounds and, with
/// recognition, the labels of the model saved beside it in [`PROGRESS_DIR`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The run's state.
    pub state: RunState,
    /// The model's labels (with recognition).
    pub labels: Option<Labels>,
    /// The model's file in [`PROGRESS_DIR`] (with recognition).
    pub model: Option<String>,
}

/// The files a sim run writes at the top of its directory, by their exact names: what `force`
/// may remove there (a user's own files, pictures included, never count).
fn is_run_file(name: &str) -> bool {
    use crate::run::plots::{ARRIVAL_PLOT, GRASP_PLOTS, PACKING_PLOT, RECOGNITION_PLOTS};
    [
        RESULTS_FILE,
        SUMMARY_FILE,
        MODEL_FILE,
        MODEL_LABELS_FILE,
        JOB_FILE,
        CONFIG_FILE,
        PROGRESS_FILE,
        PACKING_PLOT,
        ARRIVAL_PLOT,
    ]
    .iter()
    .chain(GRASP_PLOTS.iter())
    .chain(RECOGNITION_PLOTS.iter())
    .any(|f| *f == name)
}

/// `round-NNNN.mcap` or `round-NNNN.png` (digits only between), as [`RoundSink`] names them.
fn is_round_file(name: &str) -> bool {
    let Some(rest) = name.strip_prefix("round-") else {
        return false;
    };
    let Some(number) = rest
        .strip_suffix(".mcap")
        .or_else(|| rest.strip_suffix(".png"))
    else {
        return false;
    };
    !number.is_empty() && number.bytes().all(|b| b.is_ascii_digit())
}

/// `model-NNNN.lgdm` (digits only between), as [`Checkpointer::save`] names them.
fn is_progress_model(name: &str) -> bool {
    name.strip_prefix("model-")
        .and_then(|n| n.strip_suffix(".lgdm"))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// What a sim run directory holds (what `force` may remove): the files a run writes, by
/// their exact names, and its folders holding only such files (with the temporary files of
/// those being written).
fn classify(name: &str, is_dir: bool) -> Entry {
    use lgdm_base::fs::temporary_target;
    let own = |inner: &str, ours: &dyn Fn(&str) -> bool| {
        if !is_dir && (ours(inner) || temporary_target(inner).is_some_and(ours)) {
            Entry::Ours
        } else {
            Entry::Foreign
        }
    };
    let folder = || {
        if is_dir {
            Entry::Folder
        } else {
            Entry::Foreign
        }
    };
    if let Some(inner) = name.strip_prefix("progress/") {
        return own(inner, &is_progress_model);
    }
    if let Some(inner) = name.strip_prefix("rounds/") {
        return own(inner, &is_round_file);
    }
    match name {
        PROGRESS_DIR | ROUNDS_DIR => folder(),
        _ => own(name, &is_run_file),
    }
}

/// The ownership policy of sim run directories.
const OWNERSHIP: Ownership<'static> = Ownership {
    kind: "an lgdm sim run",
    occupied: "holds another run; choose another directory, pass --force to replace it, or \
               --resume to finish an interrupted one",
    classify: &classify,
};

/// A sim run directory owned by this process: locked while it lives.
#[derive(Debug)]
pub struct SimRunDir {
    dir: PathBuf,
    _lock: DirLock,
}

fn dir_error(path: &Path, reason: impl std::fmt::Display) -> SimError {
    SimError::RunDir {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

impl SimRunDir {
    /// Creates and locks `dir`. A directory that already holds files is refused, unless `force`
    /// is set and every file in it belongs to a sim run (those are removed first); a directory
    /// holding anything else is never cleared.
    pub fn create(dir: &Path, force: bool) -> Result<SimRunDir, SimError> {
        let lock = lgdm_base::fs::claim(dir, force, &OWNERSHIP)
            .map_err(|e| dir_error(&e.path, e.reason))?;
        Ok(SimRunDir {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// Reopens an unfinished run to finish it: locks it; it must hold a [`JOB_FILE`] and no
    /// [`RESULTS_FILE`] (a finished run has nothing to resume).
    pub fn reopen(dir: &Path) -> Result<SimRunDir, SimError> {
        if !dir.join(JOB_FILE).is_file() {
            return Err(dir_error(
                dir,
                format!("is not a sim run directory (no {JOB_FILE}): nothing to resume"),
            ));
        }
        let lock = DirLock::try_acquire(dir)
            .map_err(|e| dir_error(dir, e))?
            .ok_or_else(|| dir_error(dir, "another lgdm process is writing this run directory"))?;
        if dir.join(RESULTS_FILE).is_file() {
            return Err(dir_error(dir, "the run is finished: nothing to resume"));
        }
        Ok(SimRunDir {
            dir: dir.to_path_buf(),
            _lock: lock,
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes `name` (a file name, or a path such as `rounds/round-0000.mcap` whose folders
    /// are created) in the directory atomically.
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), SimError> {
        write_in(&self.dir, name, bytes)
    }

    /// Writes the [`JOB_FILE`].
    pub fn write_job(&self, job: &impl Serialize) -> Result<(), SimError> {
        let text = serde_json::to_string_pretty(job).map_err(|e| dir_error(&self.dir, e))?;
        self.write_file(JOB_FILE, (text + "\n").as_bytes())
    }

    /// Writes [`CONFIG_FILE`].
    pub fn write_config(&self, config: &crate::run::config::SimConfig) -> Result<(), SimError> {
        let text = config.to_toml().map_err(|e| dir_error(&self.dir, e))?;
        let header = "# Every constant of this run (lgdm sim --config FILE takes it back).\n";
        self.write_file(CONFIG_FILE, format!("{header}{text}").as_bytes())
    }

    /// Reads the [`JOB_FILE`] of `dir`.
    pub fn read_job<T: serde::de::DeserializeOwned>(dir: &Path) -> Result<T, SimError> {
        let path = dir.join(JOB_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| dir_error(&path, e))?;
        serde_json::from_str(&text).map_err(|e| dir_error(&path, e))
    }

    /// What writes a [`Checkpoint`] after each round (it needs no borrow of the directory, which
    /// the recording holds while the run plays).
    pub fn checkpointer(&self) -> Checkpointer {
        Checkpointer {
            dir: self.dir.clone(),
        }
    }

    /// The [`Checkpoint`] of an unfinished run with its model, if it finished a round.
    pub fn read_checkpoint(&self) -> Result<Option<(Checkpoint, Option<Gdm>)>, SimError> {
        let path = self.dir.join(PROGRESS_FILE);
        if !path.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| dir_error(&path, e))?;
        let checkpoint: Checkpoint =
            serde_json::from_str(&text).map_err(|e| dir_error(&path, e))?;
        let model = match &checkpoint.model {
            Some(name) => {
                let path = self.dir.join(PROGRESS_DIR).join(name);
                Some(Gdm::load(&path).map_err(|e| dir_error(&path, e))?)
            }
            None => None,
        };
        Ok(Some((checkpoint, model)))
    }

    /// The run is done: its [`PROGRESS_FILE`] and [`PROGRESS_DIR`] go.
    pub fn finish(&self) -> Result<(), SimError> {
        let file = self.dir.join(PROGRESS_FILE);
        if file.exists() {
            std::fs::remove_file(&file).map_err(|e| dir_error(&file, e))?;
        }
        let folder = self.dir.join(PROGRESS_DIR);
        if folder.exists() {
            std::fs::remove_dir_all(&folder).map_err(|e| dir_error(&folder, e))?;
        }
        Ok(())
    }

    /// Writes [`RESULTS_FILE`], [`SUMMARY_FILE`] and the plots
    /// ([`crate::run::plots::write_plots`]).
    pub fn write_results(&self, results: &RunResults) -> Result<(), SimError> {
        self.write_file(RESULTS_FILE, results.to_json().as_bytes())?;
        self.write_file(SUMMARY_FILE, summary_text(results).as_bytes())?;
        crate::run::plots::write_plots(&self.dir, results)?;
        Ok(())
    }

    /// Writes the model `recognizer` holds: [`MODEL_FILE`] and [`MODEL_LABELS_FILE`], which
    /// `--model`, `lgdm eval` and `lgdm.GDM.load` read.
    pub fn write_model(&self, recognizer: &Recognizer) -> Result<(), SimError> {
        let path = self.dir.join(MODEL_FILE);
        recognizer
            .model()
            .save(&path)
            .map_err(|e| dir_error(&path, e))?;
        let record = ModelRecord::new(recognizer.encoder_name(), recognizer.labels());
        self.write_file(MODEL_LABELS_FILE, record.to_json().as_bytes())
    }
}

/// Writes `name` in `dir` atomically, creating its folders.
fn write_in(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), SimError> {
    let path = dir.join(name);
    let folder = path.parent().unwrap_or(dir);
    std::fs::create_dir_all(folder).map_err(|e| dir_error(folder, e))?;
    lgdm_base::fs::write_bytes(&path, bytes).map_err(|e| dir_error(&path, e))
}

/// Writes a run's [`Checkpoint`] after each round: the model first, as a new file in
/// [`PROGRESS_DIR`], then [`PROGRESS_FILE`] naming it, then the previous model goes — so a run
/// killed at any point leaves a checkpoint whose model is there.
#[derive(Debug)]
pub struct Checkpointer {
    dir: PathBuf,
}

impl Checkpointer {
    /// Saves `state` and `recognizer`'s model.
    pub fn save(&self, state: &RunState, recognizer: Option<&Recognizer>) -> Result<(), SimError> {
        let folder = self.dir.join(PROGRESS_DIR);
        let model = recognizer
            .map(|r| -> Result<String, SimError> {
                let name = format!("model-{:04}.lgdm", state.rounds_done);
                let path = folder.join(&name);
                std::fs::create_dir_all(&folder).map_err(|e| dir_error(&folder, e))?;
                r.model().save(&path).map_err(|e| dir_error(&path, e))?;
                Ok(name)
            })
            .transpose()?;
        let checkpoint = Checkpoint {
            state: state.clone(),
            labels: recognizer.map(|r| r.labels().clone()),
            model: model.clone(),
        };
        let text = serde_json::to_string(&checkpoint).map_err(|e| dir_error(&self.dir, e))?;
        write_in(&self.dir, PROGRESS_FILE, text.as_bytes())?;
        // Earlier models are no longer named.
        if let (Some(keep), Ok(entries)) = (&model, std::fs::read_dir(&folder)) {
            for entry in entries.flatten() {
                let name = entry.file_name().to_string_lossy().into_owned();
                if is_progress_model(&name) && &name != keep {
                    let _ = std::fs::remove_file(entry.path());
                }
            }
        }
        Ok(())
    }
}

/// A run directory stores recorded rounds as `rounds/round-NNNN.mcap` and `.png`.
impl RoundSink for SimRunDir {
    fn write_round(&mut self, round: RoundRecording) -> Result<(), RecordError> {
        let stem = format!("{ROUNDS_DIR}/{}", round.file_stem());
        let failed = |e: SimError| RecordError::Write {
            path: self.dir.join(&stem).display().to_string(),
            reason: e.to_string(),
        };
        self.write_file(&format!("{stem}.mcap"), &round.mcap)
            .map_err(failed)?;
        let png = round
            .storyboard
            .encode_png()
            .map_err(|e| failed(dir_error(&self.dir, e)))?;
        self.write_file(&format!("{stem}.png"), &png)
            .map_err(failed)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policy_knows_a_run_and_nothing_else() {
        for (name, is_dir, want) in [
            ("results.json", false, Entry::Ours),
            ("summary.txt", false, Entry::Ours),
            ("model.lgdm", false, Entry::Ours),
            ("learning_curve.png", false, Entry::Ours),
            (".results.json.x1y2.tmp", false, Entry::Ours),
            (".holiday.png.x1y2.tmp", false, Entry::Foreign),
            (".notes.tmp", false, Entry::Foreign),
            ("holiday.png", false, Entry::Foreign),
            ("success_by_category.png", false, Entry::Ours),
            ("packing_by_category.png", false, Entry::Ours),
            ("rounds/round-0003-holiday.png", false, Entry::Foreign),
            ("rounds/round-.png", false, Entry::Foreign),
            ("progress/model-notes.lgdm", false, Entry::Foreign),
            ("rounds", true, Entry::Folder),
            ("rounds/round-0003.mcap", false, Entry::Ours),
            ("rounds/round-0003.png", false, Entry::Ours),
            ("rounds/holiday.jpg", false, Entry::Foreign),
            ("rounds/round-0003.mcap", true, Entry::Foreign),
            ("rounds", false, Entry::Foreign),
            ("job.json", false, Entry::Ours),
            ("progress.json", false, Entry::Ours),
            ("progress", true, Entry::Folder),
            ("progress/model-0003.lgdm", false, Entry::Ours),
            ("progress/notes.txt", false, Entry::Foreign),
            ("thesis.tex", false, Entry::Foreign),
            ("results.json", true, Entry::Foreign),
        ] {
            assert_eq!(classify(name, is_dir), want, "{name} (dir: {is_dir})");
        }
    }
}
