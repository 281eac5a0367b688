//! A run from its spec to its run directory: the constants ([`config`]), what a run is
//! ([`spec`]) and its errors ([`error`]), the objects ([`objects`]), the rounds ([`runner`],
//! calling a [`observe::RunObserver`] at each event) and where they stand ([`state`]), the
//! records ([`results`], [`report`], [`plots`]), the directory ([`run_dir`]), the jobs as one
//! call each ([`job`]) and recording ([`record`], [`captions`]). On everything but datagen.

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
