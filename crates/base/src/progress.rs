//! [`Progress`]: what long-running library calls report to their caller's callback. Libraries
//! never draw: the binary renders these as a bar or JSON lines, Python as its callback.
//!
//! ```
//! use lgdm_base::Progress;
//! let mut last = None;
//! let mut on_progress = |p: Progress| last = Some((p.stage, p.done, p.total));
//! on_progress(Progress { stage: "views", done: 3, total: 10 });
//! assert_eq!(last, Some(("views", 3, 10)));
//! ```

/// A progress report: `done` of `total` units of work in `stage`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// What is being counted (`objects`, `views`, `grasp images`, `features`, `rounds`,
    /// `attempts`).
    pub stage: &'static str,
    /// Units finished.
    pub done: u64,
    /// Units in the stage.
    pub total: u64,
}
