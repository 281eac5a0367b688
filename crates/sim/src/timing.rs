//! Where the wall-clock time of a run goes: [`WallTimes`] adds up seconds by kind of [`Work`]
//! (rendering, perception, the grasp source, planning, physics, recognition) for an attempt, a
//! round and a run. Wall times are never deterministic: results keep them in fields named
//! `wall`, apart from everything a comparison of two runs looks at.
//!
//! ```
//! use lgdm_sim::timing::{WallTimes, Work};
//! let mut wall = WallTimes::default();
//! let x = wall.time(Work::Physics, || 2 + 2);
//! assert_eq!(x, 4);
//! assert!(wall.physics_s >= 0.0 && wall.render_s == 0.0);
//! ```

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// Wall-clock seconds an attempt spent, by kind of work. Not deterministic: kept apart.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct WallTimes {
    /// Everything.
    pub total_s: f64,
    /// Rendering camera frames.
    pub render_s: f64,
    /// Segmentation, crops, grasp placement.
    pub perception_s: f64,
    /// The grasp source.
    pub source_s: f64,
    /// IK and trajectory planning.
    pub planning_s: f64,
    /// Physics steps (robot motions, settling).
    pub physics_s: f64,
    /// Recognition and learning: features of the object's views, the dual memory's prediction,
    /// the teacher's lesson and replay (rendering the views counts as rendering).
    #[serde(default)]
    pub recognition_s: f64,
}

impl WallTimes {
    /// Adds `other`, field by field.
    pub fn add(&mut self, other: &WallTimes) {
        self.total_s += other.total_s;
        self.render_s += other.render_s;
        self.perception_s += other.perception_s;
        self.source_s += other.source_s;
        self.planning_s += other.planning_s;
        self.physics_s += other.physics_s;
        self.recognition_s += other.recognition_s;
    }
}

/// What kind of work a timed span is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Work {
    /// Rendering.
    Render,
    /// Segmentation, crops, grasp placement.
    Perception,
    /// The grasp source.
    Source,
    /// IK and planning.
    Planning,
    /// Physics.
    Physics,
    /// Recognition and learning.
    Recognition,
}

impl WallTimes {
    /// Runs `f`, adding its wall time to `work`'s field.
    pub fn time<T>(&mut self, work: Work, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        let d = start.elapsed().as_secs_f64();
        match work {
            Work::Render => self.render_s += d,
            Work::Perception => self.perception_s += d,
            Work::Source => self.source_s += d,
            Work::Planning => self.planning_s += d,
            Work::Physics => self.physics_s += d,
            Work::Recognition => self.recognition_s += d,
        }
        out
    }

    /// Sets `total_s` from a start instant.
    pub fn finish(&mut self, start: Instant) {
        self.total_s = Duration::as_secs_f64(&start.elapsed());
    }
}
