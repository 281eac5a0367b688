//! `lgdm sim`: the tabletop robot (`lgdm_sim`).
//!
//! `lgdm sim grasp` plays rounds of a grasp scenario (isolated, packed, pile) with one grasp
//! source (analytic, random, or network — the grasp autoencoder, loaded once per run from
//! `--ae-checkpoint` or the shipped checkpoint, in a build with the `ae` feature) and writes a run
//! directory: `results.json` (every attempt, every round, the summary with Wilson 95 %
//! intervals, the config, wall times apart), `summary.txt`, `success_by_category.png` and
//! `failure_reasons.png`. The objects are the procedural library (`--instances` per category,
//! built from `--seed`) or the meshes of `--meshes DIR` (the `gen-dataset` layout). Every input
//! is checked before the run directory is touched: `--rounds 0`, a mesh whose convex hull
//! cannot be built or an object larger than the table are errors naming the problem.
//!
//! `--record` also writes every round (or the first `--record-rounds N`) for Foxglove:
//! `rounds/round-NNNN.mcap` (transforms of every body, the scene, camera images, the chosen
//! grasp, events; sim time, so the same seed gives the same bytes) and `rounds/round-NNNN.png`,
//! a storyboard of the round's attempts ([`lgdm_sim::record`]).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use lgdm_pointcloud::import::{MeshUnits, load_mesh_library};
use lgdm_pointcloud::objects::{CATEGORIES, ObjectModel, procedural_library};
use lgdm_sim::camera::ObjectDrawing;
use lgdm_sim::record::RecordConfig;
use lgdm_sim::run::{
    ROUNDS_DIR, RunProgress, RunResults, RunSpec, SimRunDir, builtin_source, run_trials,
    run_trials_recorded,
};
use lgdm_sim::scenario::{Scenario, check_library};
use lgdm_sim::shapes::ObjectShape;
use lgdm_sim::source::GraspSource;

use crate::plot::{Bar, write_bar_chart};
use crate::progress::{ProgressMode, Reporter};

/// Arguments of `lgdm sim`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// What to run.
    #[command(subcommand)]
    pub command: SimCommand,
}

/// `lgdm sim` subcommands.
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Grasp trials: rounds of a scenario with one grasp source → results.json, summary, plots.
    Grasp(GraspArgs),
}

/// The scenarios (`--scenario`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScenarioArg {
    /// One object at a time, up to 3 ranked grasps, reset after a failed try.
    Isolated,
    /// 5 objects pushed together.
    Packed,
    /// 5 objects dropped in a heap.
    Pile,
}

impl From<ScenarioArg> for Scenario {
    fn from(s: ScenarioArg) -> Self {
        match s {
            ScenarioArg::Isolated => Scenario::Isolated,
            ScenarioArg::Packed => Scenario::Packed,
            ScenarioArg::Pile => Scenario::Pile,
        }
    }
}

/// The grasp sources (`--grasp`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GraspArg {
    /// Antipodal grasps from the crop's depth image.
    Analytic,
    /// A random object pixel, angle and opening (a baseline).
    Random,
    /// The grasp autoencoder (needs a build with `--features ae`).
    Network,
}

/// What the cameras draw for an object (`--draw`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DrawArg {
    /// The object's mesh, as in the dataset (the collider only approximates it).
    Mesh,
    /// The physics collider in the mesh's colours (default): the camera sees what the fingers
    /// meet.
    Collider,
}

/// The objects' collider shapes (`--shapes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ShapesArg {
    /// Each object's convex hull: openings and handles are filled.
    Hull,
    /// A convex decomposition (default; VHACD, 0.1–0.5 s per object once): openings stay open.
    Decomposition,
}

/// Arguments of `lgdm sim grasp`.
#[derive(Debug, ClapArgs)]
pub struct GraspArgs {
    /// How the table is set.
    #[arg(long, value_enum, default_value_t = ScenarioArg::Isolated)]
    pub scenario: ScenarioArg,
    /// Where grasps come from.
    #[arg(long, value_enum, default_value_t = GraspArg::Analytic)]
    pub grasp: GraspArg,
    /// Rounds to play (isolated: one object each; packed and pile: 5 objects each).
    #[arg(long, default_value_t = 10)]
    pub rounds: usize,
    /// Base seed: object poses, clutter draws, the random source and the procedural instances.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run directory, new or empty: results.json, summary.txt, plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the sim run already in `--out` (its files are removed first).
    #[arg(long)]
    pub force: bool,
    /// Use meshes from <DIR>/<category>/<instance>.{obj,stl,ply} instead of procedural objects.
    #[arg(long, value_name = "DIR")]
    pub meshes: Option<PathBuf>,
    /// Units of the --meshes files: `mm`, `cm` or `m` for every file, and/or `FILE=UNIT` for one
    /// (as `gen-dataset --units`); guessed from the size when not given.
    #[arg(long, value_name = "[FILE=]UNIT", requires = "meshes")]
    pub units: Vec<String>,
    /// Procedural instances per category (default 5: 50 objects).
    #[arg(long, default_value_t = 5, conflicts_with = "meshes")]
    pub instances: usize,
    /// What the cameras draw for an object.
    #[arg(long, value_enum, default_value_t = DrawArg::Collider)]
    pub draw: DrawArg,
    /// The objects' collider shapes in the physics.
    #[arg(long, value_enum, default_value_t = ShapesArg::Decomposition)]
    pub shapes: ShapesArg,
    /// Record the rounds for Foxglove: rounds/round-NNNN.mcap and a storyboard
    /// rounds/round-NNNN.png per round.
    #[arg(long)]
    pub record: bool,
    /// Record only the first N rounds (implies --record).
    #[arg(long, value_name = "N")]
    pub record_rounds: Option<usize>,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
    /// The grasp network's checkpoint for --grasp network (default: the one shipped with
    /// train_ae, `weights/cpu.pt`).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
}

/// Runs `lgdm sim`.
pub fn run(args: Args) -> Result<()> {
    match args.command {
        SimCommand::Grasp(args) => grasp(args),
    }
}

/// Why `--grasp network` cannot run in a build without the `ae` feature, and what to do.
#[cfg_attr(feature = "ae", allow(dead_code))]
pub const NETWORK_NOT_BUILT: &str = "--grasp network needs the torch grasp autoencoder, and this \
`lgdm` binary was built without the `ae` feature (the default build neither links libpython nor \
needs torch). Rebuild it with `cargo build --release -p lgdm-cli --features ae`, and install torch \
and the autoencoder package into a venv: `python3 -m venv ~/.cache/lgdm/venv && \
~/.cache/lgdm/venv/bin/pip install -e python/train_ae` (or activate your own venv, or set \
LGDM_VENV to it); see the README, \"Grasp network\". Or use --grasp analytic or --grasp random";

/// The grasp source of `args`, loaded once for the whole run.
fn source(args: &GraspArgs, reporter: &Reporter) -> Result<Box<dyn GraspSource>> {
    if let (Some(p), false) = (&args.ae_checkpoint, args.grasp == GraspArg::Network) {
        bail!(
            "--ae-checkpoint {} only applies to --grasp network",
            p.display()
        );
    }
    match args.grasp {
        GraspArg::Analytic => Ok(builtin_source("analytic", args.seed)?),
        GraspArg::Random => Ok(builtin_source("random", args.seed)?),
        GraspArg::Network => network_source(args.ae_checkpoint.as_deref(), reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn network_source(
    _checkpoint: Option<&std::path::Path>,
    _reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    bail!(NETWORK_NOT_BUILT)
}

/// The grasp autoencoder ([`crate::network::NetworkSource`]) from `checkpoint`, else the one
/// shipped with train_ae; a missing venv, module or checkpoint is an error naming it.
#[cfg(feature = "ae")]
fn network_source(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use crate::network::NetworkSource;
    const USER: &str = "--grasp network";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let source = NetworkSource::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    reporter.message(&source.describe());
    Ok(Box::new(source))
}

/// The object library: the procedural objects or the meshes of `--meshes`.
fn library(args: &GraspArgs, reporter: &Reporter) -> Result<(Vec<ObjectModel>, String)> {
    match &args.meshes {
        None => {
            if args.instances == 0 {
                bail!("--instances 0: at least one instance per category is needed");
            }
            let objects = procedural_library(&CATEGORIES, args.instances, args.seed)?;
            Ok((objects, "procedural".into()))
        }
        Some(dir) => {
            let units = MeshUnits::parse(&args.units)
                .map_err(|reason| anyhow::anyhow!("--units: {reason}"))?;
            let imported = load_mesh_library(dir, &units)
                .with_context(|| format!("--meshes {}", dir.display()))?;
            for i in &imported {
                let warning = if i.report.is_plausible() {
                    ""
                } else {
                    " (not the 2 cm to 60 cm of a household object: check --units)"
                };
                reporter.message(&format!(
                    "mesh {}: {}{warning}",
                    i.report.file,
                    i.report.describe()
                ));
            }
            Ok((
                imported.into_iter().map(|i| i.object).collect(),
                format!("meshes {}", dir.display()),
            ))
        }
    }
}

fn grasp(args: GraspArgs) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    if args.rounds == 0 {
        bail!("--rounds 0: at least one round is needed");
    }
    let mut source = source(&args, &reporter)?;
    let (objects, objects_label) = library(&args, &reporter)?;
    let mut spec = RunSpec::new(args.scenario.into(), args.rounds, args.seed);
    spec.objects = objects_label;
    spec.config.cameras.draw = match args.draw {
        DrawArg::Mesh => ObjectDrawing::Mesh,
        DrawArg::Collider => ObjectDrawing::Collider,
    };
    spec.config.shapes.shape = match args.shapes {
        ShapesArg::Hull => ObjectShape::Hull,
        ShapesArg::Decomposition => ObjectShape::Decomposition,
    };
    // Every object must be simulable before the run directory is touched.
    check_library(&spec.config.world, &objects).context("the object library")?;
    let record = (args.record || args.record_rounds.is_some()).then(|| RecordConfig {
        first_rounds: args.record_rounds,
        ..RecordConfig::default()
    });
    let mut run_dir = SimRunDir::create(&args.out, args.force)?;
    let started = Instant::now();
    let mut task = reporter.bar("sim grasp", args.rounds as u64);
    let progress = |p: &RunProgress| {
        task.update_coarse("rounds", p.rounds_done as u64, p.rounds as u64);
    };
    let results = match &record {
        None => run_trials(&spec, &objects, source.as_mut(), progress),
        Some(config) => run_trials_recorded(
            &spec,
            &objects,
            source.as_mut(),
            progress,
            config,
            &mut run_dir,
        ),
    };
    task.finish();
    let results = results.context("running the grasp trials")?;
    run_dir.write_results(&results)?;
    let table = summary_table(&results);
    run_dir.write_file("summary.txt", table.as_bytes())?;
    write_plots(&run_dir, &results).context("drawing the plots")?;
    let s = &results.summary;
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": args.out.display().to_string(),
        "attempts": s.attempts,
        "grasp_success_rate": s.grasp_success_rate.value,
        "placement_success_rate": s.placement_success_rate.value,
        "cleared_fraction": s.cleared_fraction.value,
        "contact_only_success_rate": s.contact_only_success_rate.value,
        "seconds": started.elapsed().as_secs_f64(),
    }));
    if args.progress != ProgressMode::Jsonl {
        println!("{table}");
        if record.is_some() {
            println!(
                "recorded rounds (MCAP for Foxglove, PNG storyboards) in {}",
                args.out.join(ROUNDS_DIR).display()
            );
        }
        println!("wrote {}", args.out.display());
    }
    Ok(())
}

/// The terminal summary: rates with Wilson intervals, per category, failure reasons, where the
/// wall time went.
pub fn summary_table(r: &RunResults) -> String {
    use std::fmt::Write;
    let s = &r.summary;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "sim grasp: {} scenario, {} grasps, {} rounds, seed {}, {} ({} objects)",
        r.run.scenario,
        r.run.grasp_source,
        r.run.rounds,
        r.run.seed,
        r.run.objects,
        r.run.library_size
    );
    let _ = writeln!(out, "{:<28} rate (95 % Wilson interval, n)", "");
    for (name, rate) in [
        ("grasp success", &s.grasp_success_rate),
        ("placement success", &s.placement_success_rate),
        ("objects cleared", &s.cleared_fraction),
        ("contact-only (paper's test)", &s.contact_only_success_rate),
    ] {
        let _ = writeln!(out, "{name:<28} {}", rate.describe());
    }
    let _ = writeln!(out, "\nper category (object aimed at):");
    let _ = writeln!(
        out,
        "  {:<12} {:>8}  {:<32} placement success",
        "category", "attempts", "grasp success"
    );
    for (c, cs) in &s.per_category {
        let _ = writeln!(
            out,
            "  {c:<12} {:>8}  {:<32} {}",
            cs.attempts,
            cs.grasp_success_rate.describe(),
            cs.placement_success_rate.describe()
        );
    }
    let failures: Vec<String> = s
        .failure_reasons
        .iter()
        .filter(|(_, n)| **n > 0)
        .map(|(k, n)| format!("{k} {n}"))
        .collect();
    let _ = writeln!(
        out,
        "\nfailure reasons: {}",
        if failures.is_empty() {
            "none".to_string()
        } else {
            failures.join(", ")
        }
    );
    let w = &r.wall;
    let a = &w.attempts;
    let pct = |x: f64| {
        if a.total_s > 0.0 {
            100.0 * x / a.total_s
        } else {
            0.0
        }
    };
    let _ = writeln!(
        out,
        "wall time {:.1} s, {:.3} s per attempt (physics {:.0} %, rendering {:.0} %, perception {:.0} %, grasp source {:.0} %, planning {:.0} %), {:.0}× real time",
        w.total_s,
        w.per_attempt_s,
        pct(a.physics_s),
        pct(a.render_s),
        pct(a.perception_s),
        pct(a.source_s),
        pct(a.planning_s),
        w.real_time_factor
    );
    out
}

fn write_plots(dir: &SimRunDir, r: &RunResults) -> Result<()> {
    let s = &r.summary;
    let bars: Vec<Bar> = s
        .per_category
        .iter()
        .map(|(c, cs)| Bar {
            label: c.clone(),
            value: cs.grasp_success_rate.value.unwrap_or(0.0),
            interval: Some((
                cs.grasp_success_rate.wilson_low,
                cs.grasp_success_rate.wilson_high,
            )),
        })
        .collect();
    write_bar_chart(
        &dir.path().join("success_by_category.png"),
        &format!(
            "Grasp success by category ({}, {}; Wilson 95 %)",
            r.run.scenario, r.run.grasp_source
        ),
        "grasp success",
        &bars,
        1.05,
    )?;
    let bars: Vec<Bar> = s
        .failure_reasons
        .iter()
        .map(|(k, n)| Bar {
            label: k.replace('_', " "),
            value: *n as f64,
            interval: None,
        })
        .collect();
    let top = bars.iter().map(|b| b.value).fold(1.0, f64::max) * 1.1;
    write_bar_chart(
        &dir.path().join("failure_reasons.png"),
        &format!(
            "Failure reasons ({} attempts, {} failed)",
            s.attempts,
            s.failure_reasons.values().sum::<usize>()
        ),
        "attempts",
        &bars,
        top,
    )?;
    Ok(())
}
