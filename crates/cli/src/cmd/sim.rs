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
use lgdm_pointcloud::import::MeshUnits;
use lgdm_sim::grasping::source::GraspSource;
use lgdm_sim::grasping::source::builtin_source;
use lgdm_sim::recognition::config::RecognitionConfig;
use lgdm_sim::recognition::encoder::{GoodEncoder, ViewEncoder};
use lgdm_sim::run::config::{ConfigOverrides, SimConfig};
use lgdm_sim::run::error::SimError;
use lgdm_sim::run::job::StopToken;
use lgdm_sim::run::job::{
    GraspJob, GraspSetup, JobKind, JobRecord, Output, PickPlaceJob, PickPlaceSetup,
};
use lgdm_sim::run::objects::{ObjectLibrary, ObjectSource};
use lgdm_sim::run::record::RecordConfig;
use lgdm_sim::run::report::summary_text;
use lgdm_sim::run::results::RunResults;
use lgdm_sim::run::run_dir::ROUNDS_DIR;

use crate::data::Encoder;
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};

mod args;
mod grasp_data;
mod objects;
pub use args::*;

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

/// Why `--grasp network` cannot run in a build without the `ae` feature, and what to do.
#[cfg_attr(feature = "ae", allow(dead_code))]
pub const NETWORK_NOT_BUILT: &str = "--grasp network needs the torch grasp autoencoder, and this \
`lgdm` binary was built without the `ae` feature (the default build neither links libpython nor \
needs torch). Rebuild it with `cargo build --release -p lgdm-cli --features ae`, and install torch \
and the autoencoder package into a venv: `python3 -m venv ~/.cache/lgdm/venv && \
~/.cache/lgdm/venv/bin/pip install -e python/train_ae` (or activate your own venv, or set \
LGDM_VENV to it); see docs/guide/grasp-network.md. Or use --grasp analytic or --grasp random";

/// The grasp source `grasp`, loaded once for the whole run. `ae_encoder`: whether recognition
/// uses the autoencoder (then `--ae-checkpoint` applies without `--grasp network`); `None` for
/// commands without recognition.
fn source(
    grasp: GraspArg,
    ae_checkpoint: Option<&Path>,
    seed: u64,
    ae_encoder: Option<bool>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    if let (Some(p), false) = (
        ae_checkpoint,
        grasp == GraspArg::Network || ae_encoder == Some(true),
    ) {
        let also = if ae_encoder.is_some() {
            " and --encoder ae"
        } else {
            ""
        };
        bail!(
            "--ae-checkpoint {} only applies to --grasp network{also}",
            p.display()
        );
    }
    match grasp {
        GraspArg::Analytic => Ok(builtin_source("analytic", seed)?),
        GraspArg::Random => Ok(builtin_source("random", seed)?),
        GraspArg::Network => network_source(ae_checkpoint, reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn network_source(_: Option<&std::path::Path>, _: &Reporter) -> Result<Box<dyn GraspSource>> {
    bail!(NETWORK_NOT_BUILT)
}

/// The grasp autoencoder (`lgdm_pybridge::ae::robot::NetworkSource`) from `checkpoint`, else
/// the one shipped with train_ae; a missing venv, module or checkpoint is an error naming it.
#[cfg(feature = "ae")]
fn network_source(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use lgdm_pybridge::ae::robot::NetworkSource;
    const USER: &str = "--grasp network";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let source = NetworkSource::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    reporter.message(&source.describe());
    Ok(Box::new(source))
}

/// The view encoder: GOOD, or with `ae` the autoencoder (from `checkpoint`).
fn view_encoder(
    ae: bool,
    checkpoint: Option<&Path>,
    reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    match ae {
        false => Ok(Box::new(GoodEncoder)),
        true => ae_view_encoder(checkpoint, reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn ae_view_encoder(_: Option<&std::path::Path>, _: &Reporter) -> Result<Box<dyn ViewEncoder>> {
    bail!(crate::data::ae::NOT_BUILT)
}

/// The autoencoder as recognition's encoder (`lgdm_pybridge::ae::robot::AeViewEncoder`).
#[cfg(feature = "ae")]
fn ae_view_encoder(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use lgdm_pybridge::ae::robot::AeViewEncoder;
    const USER: &str = "--encoder ae";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let encoder = AeViewEncoder::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    let from = checkpoint.display();
    reporter.message(&format!("recognition: autoencoder features from {from}"));
    Ok(Box::new(encoder))
}

/// The objects of `--meshes` (with `--units`), else the procedural ones.
fn objects(args: &RobotArgs, procedural: ObjectSource) -> Result<ObjectSource> {
    mesh_objects(args.meshes.as_ref(), &args.units, procedural)
}

/// The objects of `meshes` (with `units`), else `procedural`.
fn mesh_objects(
    meshes: Option<&std::path::PathBuf>,
    units: &[String],
    procedural: ObjectSource,
) -> Result<ObjectSource> {
    let Some(dir) = meshes else {
        return Ok(procedural);
    };
    let units = MeshUnits::parse(units).map_err(|reason| anyhow::anyhow!("--units: {reason}"))?;
    Ok(ObjectSource::Meshes {
        dir: dir.clone(),
        units,
    })
}

/// Each imported mesh's unit and size, with a warning for one that is not household-sized.
fn report_meshes(library: &ObjectLibrary, reporter: &Reporter) {
    for report in &library.imported {
        let warning = if report.is_plausible() {
            ""
        } else {
            " (not the 2 cm to 60 cm of a household object: check --units)"
        };
        reporter.message(&format!(
            "mesh {}: {}{warning}",
            report.file,
            report.describe()
        ));
    }
}

/// The run's constants: `--config`'s file (else the defaults), with what the options set — the
/// gripper, the cameras' drawing, the colliders — on top. Checked whole, naming the field.
fn sim_config(args: &RobotArgs) -> Result<SimConfig> {
    let overrides = ConfigOverrides {
        gripper: args.gripper,
        draw: args.draw,
        shapes: args.shapes,
        proposal_check: args.proposal_check,
    };
    resolve_config(args.config.as_deref(), args.out.as_deref(), &overrides)
}

/// `config` (else the defaults) with `overrides` on top, refused inside `out`.
fn resolve_config(
    config: Option<&Path>,
    out: Option<&Path>,
    overrides: &ConfigOverrides,
) -> Result<SimConfig> {
    if let (Some(config), Some(out)) = (config, out)
        && let (Ok(config), Ok(out)) = (config.canonicalize(), out.canonicalize())
        && config.starts_with(&out)
    {
        bail!(
            "--config {} is inside --out {}: a run does not write over its inputs; copy it out \
             first",
            config.display(),
            out.display()
        );
    }
    SimConfig::resolve(config, overrides).map_err(|e| anyhow::anyhow!("--config {e}"))
}

/// `--record` / `--record-rounds`.
fn record_config(args: &RobotArgs) -> Option<RecordConfig> {
    (args.record || args.record_rounds.is_some()).then(|| RecordConfig {
        first_rounds: args.record_rounds,
        ..RecordConfig::default()
    })
}

fn output(args: &RobotArgs) -> Option<Output> {
    args.out.clone().map(|dir| Output {
        dir,
        force: args.force,
    })
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

/// The grasp source a resumed run's record names.
fn recorded_grasp(name: &str) -> Result<GraspArg> {
    match name {
        "analytic" => Ok(GraspArg::Analytic),
        "random" => Ok(GraspArg::Random),
        "network" => Ok(GraspArg::Network),
        other => bail!("the run's record names an unknown grasp source `{other}`"),
    }
}

/// The job record of the run `--resume` names, with its setup pointed at that directory.
fn resumed(dir: &Path) -> Result<(JobRecord, Output)> {
    let record = JobRecord::read(dir).map_err(cli_error)?;
    Ok((record, Output::new(dir)))
}

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
        "cleared_fraction": s.cleared_fraction.value,
        "packing_success_rate": s.packing.as_ref().and_then(|p| p.success_rate.value),
        "early_category_accuracy_at_end": s.early_category_accuracy_at_end.and_then(|r| r.value),
        "seconds": started.elapsed().as_secs_f64(),
    }));
    print_end(robot.progress, &out, recorded, &results)
}

/// The setup of a new pick-place or packing run from its options.
fn new_pick_place(args: &PickPlaceArgs, targets: Option<Vec<String>>) -> Result<PickPlaceSetup> {
    let robot = &args.robot;
    let procedural = ObjectSource::Procedural {
        instances: 5,
        seed: args.object_seed,
    };
    let encoder_dim = match args.encoder {
        Encoder::Good => GoodEncoder.dim(),
        Encoder::Ae => crate::data::ae::FEATURE_DIM,
    };
    Ok(PickPlaceSetup {
        scenario: args.scenario.into(),
        rounds: args.rounds,
        attempts: args.attempts,
        seed: args.seed,
        objects: objects(robot, procedural)?,
        set_size: args.objects,
        model: args.model.clone(),
        recognition: RecognitionConfig {
            replay: !args.no_replay,
            learn_known: args.learn_always,
            confidence_threshold: args.confidence,
            ..RecognitionConfig::default()
        },
        encoder: (args.encoder.name().to_string(), encoder_dim),
        targets,
        arrive_after: args.arrive_after,
        config: sim_config(robot)?,
        record: record_config(robot),
        out: output(robot),
        ae_checkpoint: robot.ae_checkpoint.clone(),
    })
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
