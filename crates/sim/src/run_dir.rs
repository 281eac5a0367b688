//! A sim run directory, owned the way `lgdm train --out` owns its own: a new or empty
//! directory, or with `force` one that holds only a previous sim run's files (the ownership
//! policy of [`lgdm_base::fs::claim`]); locked while the run writes; every file written
//! atomically. It holds [`RESULTS_FILE`], [`SUMMARY_FILE`], with recognition [`MODEL_FILE`] and
//! [`MODEL_LABELS_FILE`], with recording [`ROUNDS_DIR`]`/round-NNNN.{mcap,png}`, and the
//! binary's plots (`*.png`).
//!
//! ```
//! use lgdm_sim::run_dir::SimRunDir;
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

use crate::model::{MODEL_FILE, MODEL_LABELS_FILE, ModelRecord};
use crate::recognize::Recognizer;
use crate::record::{RecordError, RoundRecording, RoundSink};
use crate::report::summary_text;
use crate::results::{RESULTS_FILE, RunResults};
use crate::spec::SimError;

/// The run's summary as text (the binary prints the same).
pub const SUMMARY_FILE: &str = "summary.txt";

/// The folder of a run directory that holds the recorded rounds.
pub const ROUNDS_DIR: &str = "rounds";

/// What a sim run directory holds (what `force` may remove).
fn classify(name: &str, is_dir: bool) -> Entry {
    let temporary = |n: &str| n.starts_with('.') && n.ends_with(".tmp");
    if let Some(inner) = name.strip_prefix("rounds/") {
        // Recorded rounds: only round files may be in there.
        let round =
            inner.starts_with("round-") && (inner.ends_with(".mcap") || inner.ends_with(".png"));
        return if !is_dir && (round || temporary(inner)) {
            Entry::Ours
        } else {
            Entry::Foreign
        };
    }
    if name == ROUNDS_DIR {
        return if is_dir {
            Entry::Folder
        } else {
            Entry::Foreign
        };
    }
    let ours = matches!(
        name,
        RESULTS_FILE | SUMMARY_FILE | MODEL_FILE | MODEL_LABELS_FILE
    ) || name.ends_with(".png")
        || temporary(name);
    if ours && !is_dir {
        Entry::Ours
    } else {
        Entry::Foreign
    }
}

/// The ownership policy of sim run directories.
const OWNERSHIP: Ownership<'static> = Ownership {
    kind: "an lgdm sim run",
    occupied: "holds another run; choose another directory or pass --force to replace it",
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

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Writes `name` (a file name, or a path such as `rounds/round-0000.mcap` whose folders
    /// are created) in the directory atomically.
    pub fn write_file(&self, name: &str, bytes: &[u8]) -> Result<(), SimError> {
        let path = self.dir.join(name);
        let folder = path.parent().unwrap_or(&self.dir);
        std::fs::create_dir_all(folder).map_err(|e| dir_error(folder, e))?;
        lgdm_base::fs::write_bytes(&path, bytes).map_err(|e| dir_error(&path, e))
    }

    /// Writes [`RESULTS_FILE`] and [`SUMMARY_FILE`].
    pub fn write_results(&self, results: &RunResults) -> Result<(), SimError> {
        self.write_file(RESULTS_FILE, results.to_json().as_bytes())?;
        self.write_file(SUMMARY_FILE, summary_text(results).as_bytes())
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
            ("rounds", true, Entry::Folder),
            ("rounds/round-0003.mcap", false, Entry::Ours),
            ("rounds/round-0003.png", false, Entry::Ours),
            ("rounds/holiday.jpg", false, Entry::Foreign),
            ("rounds/round-0003.mcap", true, Entry::Foreign),
            ("rounds", false, Entry::Foreign),
            ("thesis.tex", false, Entry::Foreign),
            ("results.json", true, Entry::Foreign),
        ] {
            assert_eq!(classify(name, is_dir), want, "{name} (dir: {is_dir})");
        }
    }
}
