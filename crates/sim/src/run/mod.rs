//! A run of the robot: its config and spec, the rounds, their results and the run directory.

pub mod captions;
pub mod config;
pub mod error;
pub mod job;
pub mod objects;
pub mod observe;
pub mod plots;
pub mod record;
pub mod report;
pub mod results;
pub mod run_dir;
pub mod runner;
pub mod spec;
pub mod state;
