//! `lgdm merge`: combine the trials of several run directories of one experiment into one run.
//!
//! Trial t of `lgdm train --trials N --seed S` uses seed S + t, so a 5-trial experiment can be
//! run as five `--trials 1 --seed k` runs (in parallel, on several machines, or across sessions)
//! and merged afterwards: the merged `metrics.json`, summary table and plots are those of the
//! 5-trial run. Runs are only merged when they are the same experiment: scenario, encoder (for
//! `--encoder ae`, the checkpoint's bytes), dataset, replay, epochs, evaluation settings and
//! every hyperparameter (the seed aside) must agree, and no seed may appear twice. Everything is
//! checked before anything is written. The checks and the merge are the library's
//! (`lgdm_gdm::experiment::run_dir`); this command writes and prints.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args as ClapArgs;
use lgdm_gdm::experiment::report::summary_table;
use lgdm_gdm::experiment::run_dir::merge_into;

use crate::output::{errln, outln};

/// Arguments of `lgdm merge`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Run directories written by `lgdm train` (each with metrics.json and config.toml).
    #[arg(required = true, num_args = 1..)]
    pub runs: Vec<PathBuf>,
    /// Output run directory, new or empty (none of the inputs): metrics.json, config.toml,
    /// plots, summary.txt and links to the trials' models.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the run already in `--out` (its files are removed first; never an input).
    #[arg(long)]
    pub force: bool,
}

/// Runs `lgdm merge`.
pub fn run(args: Args) -> Result<()> {
    let (merged, missing) = merge_into(&args.runs, &args.out, args.force)?;
    let metrics = &merged.metrics;
    let seeds: Vec<u64> = metrics.trials.iter().map(|t| t.seed).collect();
    if seeds.windows(2).any(|w| w[1] != w[0] + 1) {
        errln!(
            "note: the seeds {seeds:?} are not consecutive; the merged run is not the same as one \
             `lgdm train --trials {}` run",
            seeds.len()
        );
    }
    let out = &args.out;
    if missing > 0 {
        errln!(
            "note: {missing} trial model(s) were not found next to their metrics.json and are not linked"
        );
    }
    outln!("{}", summary_table(metrics))?;
    outln!(
        "merged {} run(s), {} trial(s), seeds {seeds:?}: {}",
        args.runs.len(),
        metrics.trials.len(),
        out.display()
    )?;
    Ok(())
}
