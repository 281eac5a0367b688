//! Progress rendering for long commands: an indicatif bar, JSON lines on stderr, or nothing.
//!
//! Libraries report progress through callbacks; only this module draws. Usage:
//! ```ignore
//! let reporter = Reporter::new(ProgressMode::Bar);
//! let bar = reporter.bar("render", 0);
//! bar.update("render", 10, 100);
//! bar.finish();
//! ```

use indicatif::{ProgressBar, ProgressStyle};

use crate::output::errln;

/// How progress is shown (`--progress`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressMode {
    /// A progress bar on stderr (hidden when stderr is not a terminal).
    #[default]
    Bar,
    /// One JSON object per line on stderr: `{"event":"progress","task":..,"stage":..,"done":..,"total":..}`.
    Jsonl,
    /// Nothing.
    None,
}

/// Renders progress and messages in the chosen mode.
#[derive(Clone, Debug)]
pub struct Reporter {
    mode: ProgressMode,
}

impl Reporter {
    /// A reporter in the given mode.
    pub fn new(mode: ProgressMode) -> Reporter {
        Reporter { mode }
    }

    /// A one-line note for the user (stderr; a JSON line in `jsonl` mode; dropped in `none`).
    pub fn message(&self, text: &str) {
        match self.mode {
            ProgressMode::Bar => errln!("{text}"),
            ProgressMode::Jsonl => {
                json_line(&serde_json::json!({ "event": "message", "text": text }))
            }
            ProgressMode::None => {}
        }
    }

    /// Emits a structured event (JSON lines mode only).
    pub fn event(&self, value: &serde_json::Value) {
        if self.mode == ProgressMode::Jsonl {
            json_line(value);
        }
    }

    /// A task with a count of work items; `total` may be 0 when not yet known.
    pub fn bar(&self, task: &str, total: u64) -> Task {
        let bar = match self.mode {
            ProgressMode::Bar => {
                let b = ProgressBar::new(total);
                b.set_style(
                    ProgressStyle::with_template(
                        "{prefix:>14} [{elapsed_precise}] {wide_bar} {pos}/{len} {msg} (eta {eta})",
                    )
                    .expect("valid template"),
                );
                b.set_prefix(task.to_string());
                Some(b)
            }
            _ => None,
        };
        Task {
            mode: self.mode,
            task: task.to_string(),
            bar,
            last_emitted: None,
        }
    }
}

fn json_line(value: &serde_json::Value) {
    errln!("{value}");
}

/// One task's progress.
#[derive(Debug)]
pub struct Task {
    mode: ProgressMode,
    task: String,
    bar: Option<ProgressBar>,
    last_emitted: Option<(u64, u64)>,
}

impl Task {
    /// Reports `done` of `total` work items in a stage.
    pub fn update(&self, stage: &str, done: u64, total: u64) {
        match self.mode {
            ProgressMode::Bar => {
                if let Some(b) = &self.bar {
                    if b.length() != Some(total) {
                        b.set_length(total);
                    }
                    b.set_position(done);
                    b.set_message(stage.to_string());
                }
            }
            ProgressMode::Jsonl => json_line(&serde_json::json!({
                "event": "progress", "task": self.task, "stage": stage, "done": done, "total": total
            })),
            ProgressMode::None => {}
        }
    }

    /// Like `update`, but in JSON-lines mode emits only when the percentage changes.
    pub fn update_coarse(&mut self, stage: &str, done: u64, total: u64) {
        let pct = (done * 100).checked_div(total).unwrap_or(0);
        if self.mode == ProgressMode::Jsonl {
            if self.last_emitted == Some((pct, total)) && done != total {
                return;
            }
            self.last_emitted = Some((pct, total));
        }
        self.update(stage, done, total);
    }

    /// Ends the task (clears the bar).
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
