//! `lgdm sim`: the tabletop robot (`lgdm_sim`).
//!
//! `lgdm sim grasp` plays rounds of a grasp scenario (isolated, packed, pile, scattered) with one
//! grasp source (analytic, random, or network — the grasp autoencoder, loaded once per run from
//! `--ae-checkpoint` or the shipped checkpoint, in a build with the `ae` feature) and writes a run
//! directory: `results.json` (every attempt, every round, the summary with Wilson 95 %
//! intervals, the config, wall times apart), `summary.txt`, `success_by_category.png` and
//! `failure_reasons.png`. The objects are the procedural library (`--instances` per category,
//! built from `--seed`) or the meshes of `--meshes DIR` (the `gen-dataset` layout). Every input
//! is checked before the run directory is touched: `--rounds 0`, a mesh whose convex hull
//! cannot be built or an object larger than the table are errors naming the problem.
//!
//! `lgdm sim pick-place` adds recognition in the loop (the dual memory's first guess, a simulated
//! teacher, learning on the spot, replay after each round) and places everything in the left
//! basket; `--arrive-after K` lets the categories arrive over time (the first half of the object
//! set's categories before round K, the rest from K on) and ends with the model's first guess
//! about every object from fresh views (`early_category_accuracy_at_end`). `lgdm sim packing
//! --targets mug,can` is the same run with the same options, except that each object goes to the
//! basket of the category the robot recognises it as — the targets to the right basket,
//! everything else to the left — and an attempt succeeds only in the basket of the object's true
//! category ([`lgdm_sim::packing`]).
//!
//! `--record` also writes every round (or the first `--record-rounds N`) for Foxglove:
//! `rounds/round-NNNN.mcap` (transforms of every body, the scene, camera images, the chosen
//! grasp, events; sim time, so the same seed gives the same bytes) and `rounds/round-NNNN.png`,
//! a storyboard of the round's attempts ([`lgdm_sim::record`]).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use lgdm_gdm::Gdm;
use lgdm_pointcloud::import::{MeshUnits, load_mesh_library};
use lgdm_pointcloud::objects::{CATEGORIES, ObjectModel, procedural_library};
use lgdm_sim::arrival::Arrival;
use lgdm_sim::camera::ObjectDrawing;
use lgdm_sim::packing::{PackingSpec, basket_name, known_categories};
use lgdm_sim::recognize::{
    GoodEncoder, Labels, MemoryPoint, RecognitionConfig, RecognitionRecord, Recognizer, ViewEncoder,
};
use lgdm_sim::record::RecordConfig;
use lgdm_sim::run::{
    MODEL_FILE, MODEL_LABELS_FILE, ROUNDS_DIR, RunProgress, RunResults, RunSpec, SimRunDir,
    builtin_source, run_pick_place, run_trials, run_trials_recorded,
};
use lgdm_sim::scenario::{Scenario, check_library, interleaved_order};
use lgdm_sim::shapes::ObjectShape;
use lgdm_sim::source::GraspSource;

use crate::data::Encoder;
use crate::plot::{Bar, write_bar_chart, write_lines};
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
    /// The paper's pick-and-place: recognise each object with the dual memory (a simulated
    /// teacher labels what the robot does not know or gets wrong; it learns on the spot, replay
    /// after each round), grasp it, place it in the left basket.
    PickPlace(PickPlaceArgs),
    /// The paper's packing: pick-and-place with recognition where the target categories go to
    /// the right basket and everything else to the left, by what the robot recognises; success
    /// only in the basket of the object's true category.
    Packing(PackingArgs),
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
    /// 5 objects placed apart at random (the paper's pick-and-place table).
    Scattered,
}

impl From<ScenarioArg> for Scenario {
    fn from(s: ScenarioArg) -> Self {
        match s {
            ScenarioArg::Isolated => Scenario::Isolated,
            ScenarioArg::Packed => Scenario::Packed,
            ScenarioArg::Pile => Scenario::Pile,
            ScenarioArg::Scattered => Scenario::Scattered,
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

/// What every robot run takes: the grasp source, the objects, the physics and cameras, the
/// output, recording and progress.
#[derive(Debug, ClapArgs)]
pub struct RobotArgs {
    /// Where grasps come from.
    #[arg(long, value_enum, default_value_t = GraspArg::Analytic)]
    pub grasp: GraspArg,
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
    /// The autoencoder's checkpoint for --grasp network and pick-place's --encoder ae
    /// (default: the one shipped with train_ae, `weights/cpu.pt`).
    #[arg(long, value_name = "PATH")]
    pub ae_checkpoint: Option<PathBuf>,
}

/// Arguments of `lgdm sim grasp`.
#[derive(Debug, ClapArgs)]
pub struct GraspArgs {
    /// How the table is set.
    #[arg(long, value_enum, default_value_t = ScenarioArg::Isolated)]
    pub scenario: ScenarioArg,
    /// Rounds to play (isolated: one object each; packed, pile and scattered: 5 objects each).
    #[arg(long, default_value_t = 10)]
    pub rounds: usize,
    /// Base seed: object poses, clutter draws, the random source and the procedural instances.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Procedural instances per category (default 5: 50 objects).
    #[arg(long, default_value_t = 5, conflicts_with = "meshes")]
    pub instances: usize,
    /// Source, objects, output, recording.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Arguments of `lgdm sim pick-place`.
#[derive(Debug, ClapArgs)]
pub struct PickPlaceArgs {
    /// How the table is set: scattered (5 objects apart at random, the paper's table; default),
    /// packed (pushed together) or pile.
    #[arg(long, value_enum, default_value_t = ScenarioArg::Scattered)]
    pub scenario: ScenarioArg,
    /// Rounds to play (5 objects each; default when --attempts is not given either: 10 for
    /// pick-place, 50 for packing).
    #[arg(long)]
    pub rounds: Option<usize>,
    /// Stop after this many grasp attempts (750 gives the paper's shape).
    #[arg(long)]
    pub attempts: Option<usize>,
    /// Base seed: object poses, the rounds' draws, the random source, the views.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The object set: the first N objects taken category by category in turn (the first
    /// instance of every category, then the second, …; 15: the paper's set).
    #[arg(long, default_value_t = 15)]
    pub objects: usize,
    /// Seed of the procedural instances (default 0: the embedded dataset's and `gen-dataset`'s
    /// default, so a model trained on it knows these objects).
    #[arg(long, default_value_t = 0, conflicts_with = "meshes")]
    pub object_seed: u64,
    /// Start from this model (`lgdm train`'s model-trial<t>.lgdm, or a pick-place run's
    /// model.lgdm) instead of an empty one; its label names come from the run record beside it.
    #[arg(long, value_name = "CKPT")]
    pub model: Option<PathBuf>,
    /// No intrinsic replay after each round.
    #[arg(long)]
    pub no_replay: bool,
    /// Learn every object met, also the ones the robot knew (its own labels), not only the
    /// teacher's lessons: more learning in the loop, hence more that could be forgotten.
    #[arg(long)]
    pub learn_always: bool,
    /// The features recognition uses: good (GOOD, 675 values) or ae (the grasp autoencoder's
    /// 256-d feature; an `ae` build). A --model must have been trained with the same encoder.
    #[arg(long, value_enum, default_value_t = Encoder::Good)]
    pub encoder: Encoder,
    /// Below this share of agreeing views the robot says "I don't know this" (0..=1).
    #[arg(long, default_value_t = 0.6)]
    pub confidence: f64,
    /// Categories arrive over time: rounds before K show only the first half of the object
    /// set's categories, rounds from K on only the rest; at the end, the model's first guess
    /// about every object from fresh views, no teacher (results.json:
    /// early_category_accuracy_at_end). Compare with and without --no-replay.
    #[arg(long, value_name = "K")]
    pub arrive_after: Option<usize>,
    /// Source, objects, output, recording.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Arguments of `lgdm sim packing`: pick-place's, and the target categories.
#[derive(Debug, ClapArgs)]
pub struct PackingArgs {
    /// The target categories, comma-separated (e.g. mug,can): packed into the right basket;
    /// every other category into the left one.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        value_name = "CATEGORIES"
    )]
    pub targets: Vec<String>,
    /// Everything pick-place takes.
    #[command(flatten)]
    pub run: PickPlaceArgs,
}

/// Runs `lgdm sim`.
pub fn run(args: Args) -> Result<()> {
    match args.command {
        SimCommand::Grasp(args) => grasp(args),
        SimCommand::PickPlace(args) => recognition_run(args, None),
        SimCommand::Packing(args) => recognition_run(args.run, Some(args.targets)),
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

/// The grasp source of `args`, loaded once for the whole run. `ae_encoder`: whether
/// recognition uses the autoencoder (then `--ae-checkpoint` applies without `--grasp
/// network`); `None` for commands without recognition.
fn source(
    args: &RobotArgs,
    seed: u64,
    ae_encoder: Option<bool>,
    reporter: &Reporter,
) -> Result<Box<dyn GraspSource>> {
    if let (Some(p), false) = (
        &args.ae_checkpoint,
        args.grasp == GraspArg::Network || ae_encoder == Some(true),
    ) {
        bail!(
            "--ae-checkpoint {} only applies to --grasp network{}",
            p.display(),
            if ae_encoder.is_some() {
                " and --encoder ae"
            } else {
                ""
            }
        );
    }
    match args.grasp {
        GraspArg::Analytic => Ok(builtin_source("analytic", seed)?),
        GraspArg::Random => Ok(builtin_source("random", seed)?),
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
fn library(
    args: &RobotArgs,
    instances: usize,
    seed: u64,
    reporter: &Reporter,
) -> Result<(Vec<ObjectModel>, String)> {
    match &args.meshes {
        None => {
            if instances == 0 {
                bail!("--instances 0: at least one instance per category is needed");
            }
            let objects = procedural_library(&CATEGORIES, instances, seed)?;
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
    let reporter = Reporter::new(args.robot.progress);
    if args.rounds == 0 {
        bail!("--rounds 0: at least one round is needed");
    }
    let robot = &args.robot;
    let mut source = source(robot, args.seed, None, &reporter)?;
    let (objects, objects_label) = library(robot, args.instances, args.seed, &reporter)?;
    let spec = run_spec(
        robot,
        args.scenario.into(),
        args.rounds,
        args.seed,
        objects_label,
    );
    // Every object must be simulable before the run directory is touched.
    check_library(&spec.config.world, &objects).context("the object library")?;
    let record = record_config(robot);
    let mut run_dir = SimRunDir::create(&robot.out, robot.force)?;
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
        "out": robot.out.display().to_string(),
        "attempts": s.attempts,
        "grasp_success_rate": s.grasp_success_rate.value,
        "placement_success_rate": s.placement_success_rate.value,
        "cleared_fraction": s.cleared_fraction.value,
        "contact_only_success_rate": s.contact_only_success_rate.value,
        "seconds": started.elapsed().as_secs_f64(),
    }));
    print_end(robot, &table, record.is_some());
    Ok(())
}

/// The run spec both commands share: the scenario, rounds and seed, the cameras' drawing and
/// the colliders of `args`.
fn run_spec(
    args: &RobotArgs,
    scenario: Scenario,
    rounds: usize,
    seed: u64,
    objects: String,
) -> RunSpec {
    let mut spec = RunSpec::new(scenario, rounds, seed);
    spec.objects = objects;
    spec.config.cameras.draw = match args.draw {
        DrawArg::Mesh => ObjectDrawing::Mesh,
        DrawArg::Collider => ObjectDrawing::Collider,
    };
    spec.config.shapes.shape = match args.shapes {
        ShapesArg::Hull => ObjectShape::Hull,
        ShapesArg::Decomposition => ObjectShape::Decomposition,
    };
    spec
}

/// `--record` / `--record-rounds`.
fn record_config(args: &RobotArgs) -> Option<RecordConfig> {
    (args.record || args.record_rounds.is_some()).then(|| RecordConfig {
        first_rounds: args.record_rounds,
        ..RecordConfig::default()
    })
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
    let _ = writeln!(
        out,
        "\nfailure reasons: {}",
        failure_list(&s.failure_reasons)
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
        "wall time {:.1} s, {:.3} s per attempt (physics {:.0} %, rendering {:.0} %, perception \
         {:.0} %, grasp source {:.0} %, planning {:.0} %), {:.0}× real time",
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

/// What a model's ids mean and which encoder made its features: the fields of `lgdm train`'s
/// `metrics.json` (or a pick-place run's `model.json`) beside the checkpoint.
#[derive(Debug, serde::Deserialize, serde::Serialize)]
struct ModelRecord {
    encoder: String,
    categories: Vec<String>,
    #[serde(default)]
    instances: Vec<String>,
}

/// The record beside `model`: `metrics.json` (`lgdm train`) or `model.json` (pick-place).
fn model_record(model: &std::path::Path) -> Result<Option<(PathBuf, ModelRecord)>> {
    let dir = model.parent().unwrap_or(std::path::Path::new("."));
    for name in [
        lgdm_gdm::experiment::run_dir::METRICS_FILE,
        MODEL_LABELS_FILE,
    ] {
        let path = dir.join(name);
        if let Ok(text) = std::fs::read_to_string(&path) {
            let record: ModelRecord = serde_json::from_str(&text).with_context(|| {
                format!(
                    "reading the model's record {} (encoder and label names)",
                    path.display()
                )
            })?;
            return Ok(Some((path, record)));
        }
    }
    Ok(None)
}

/// The view encoder of `--encoder`.
fn view_encoder(args: &PickPlaceArgs, reporter: &Reporter) -> Result<Box<dyn ViewEncoder>> {
    match args.encoder {
        Encoder::Good => Ok(Box::new(GoodEncoder)),
        Encoder::Ae => ae_view_encoder(args.robot.ae_checkpoint.as_deref(), reporter),
    }
}

#[cfg(not(feature = "ae"))]
fn ae_view_encoder(
    _checkpoint: Option<&std::path::Path>,
    _reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    bail!(crate::data::ae::NOT_BUILT)
}

/// The autoencoder as recognition's encoder ([`crate::network::AeViewEncoder`]).
#[cfg(feature = "ae")]
fn ae_view_encoder(
    checkpoint: Option<&std::path::Path>,
    reporter: &Reporter,
) -> Result<Box<dyn ViewEncoder>> {
    use crate::data::ae::{bridge_error, resolve_checkpoint};
    use crate::network::AeViewEncoder;
    const USER: &str = "--encoder ae";
    let checkpoint = resolve_checkpoint(checkpoint, USER)?;
    let encoder = AeViewEncoder::load(&checkpoint).map_err(|e| bridge_error(e, USER))?;
    reporter.message(&format!(
        "recognition: autoencoder features from {}",
        checkpoint.display()
    ));
    Ok(Box::new(encoder))
}

/// The recognizer: `--model` (checked: its feature dimension and encoder against
/// `--encoder`'s) with the label names of its run, else an empty model with the dataset's ids
/// of `library`.
fn recognizer(
    args: &PickPlaceArgs,
    library: &[ObjectModel],
    reporter: &Reporter,
) -> Result<Recognizer> {
    if !(0.0..=1.0).contains(&args.confidence) {
        bail!("--confidence {}: must be in 0..=1", args.confidence);
    }
    let config = RecognitionConfig {
        replay: !args.no_replay,
        learn_known: args.learn_always,
        confidence_threshold: args.confidence,
        ..RecognitionConfig::default()
    };
    let encoder_name = args.encoder.name();
    let Some(model) = &args.model else {
        return Ok(Recognizer::empty_with_encoder(
            config,
            view_encoder(args, reporter)?,
            Labels::of_objects(library),
            args.seed,
        )?);
    };
    let gdm = Gdm::load(model).with_context(|| format!("--model {}", model.display()))?;
    let labels = match model_record(model)? {
        Some((path, record)) => {
            if record.encoder != encoder_name {
                bail!(
                    "--model {}: the model was trained with the `{}` encoder ({}), this run \
                     recognises with `{encoder_name}`: pass --encoder {} or a model trained on \
                     {encoder_name} features",
                    model.display(),
                    record.encoder,
                    path.display(),
                    record.encoder
                );
            }
            Labels {
                categories: record.categories,
                instances: record.instances,
            }
        }
        None => {
            reporter.message(&format!(
                "note: no run record (metrics.json or model.json) beside {}: its encoder \
                 cannot be checked and its ids are taken as the dataset ids of the object library",
                model.display()
            ));
            Labels::of_objects(library)
        }
    };
    // The dimension is checked before the encoder (and torch) is loaded.
    let dim = match args.encoder {
        Encoder::Good => GoodEncoder.dim(),
        Encoder::Ae => crate::data::ae::FEATURE_DIM,
    };
    if gdm.dim() != dim {
        let e = lgdm_sim::recognize::RecognitionError::Dimension {
            model: gdm.dim(),
            name: encoder_name.to_string(),
            encoder: dim,
        };
        return Err(anyhow::Error::new(e).context(format!("--model {}", model.display())));
    }
    let recognizer = Recognizer::with_encoder(
        config,
        view_encoder(args, reporter)?,
        gdm,
        labels,
        args.seed,
    )
    .with_context(|| format!("--model {}", model.display()))?;
    Ok(recognizer.with_origin(model.display().to_string()))
}

/// `--targets`: trimmed, duplicates dropped (first kept), none empty.
fn parse_targets(targets: &[String]) -> Result<Vec<String>> {
    let mut out: Vec<String> = Vec::new();
    for t in targets {
        let t = t.trim();
        if t.is_empty() {
            bail!("--targets: an empty category name (give e.g. --targets mug,can)");
        }
        if !out.iter().any(|o| o == t) {
            out.push(t.to_string());
        }
    }
    if out.is_empty() {
        bail!("--targets: no category given (give e.g. --targets mug,can)");
    }
    Ok(out)
}

/// `sim pick-place`, or with `targets` `sim packing`: one runner, one set of options.
fn recognition_run(args: PickPlaceArgs, targets: Option<Vec<String>>) -> Result<()> {
    let command = if targets.is_some() {
        "sim packing"
    } else {
        "sim pick-place"
    };
    let robot = &args.robot;
    let targets = targets.as_deref().map(parse_targets).transpose()?;
    let reporter = Reporter::new(robot.progress);
    if args.rounds == Some(0) {
        bail!("--rounds 0: at least one round is needed");
    }
    if args.attempts == Some(0) {
        bail!("--attempts 0: at least one attempt is needed");
    }
    if args.objects == 0 {
        bail!("--objects 0: the object set needs at least one object");
    }
    let scenario: Scenario = args.scenario.into();
    if scenario == Scenario::Isolated {
        bail!(
            "--scenario isolated: {} sets 5 objects per round; use scattered, packed or pile",
            command.trim_start_matches("sim ")
        );
    }
    let mut source = source(
        robot,
        args.seed,
        Some(args.encoder == Encoder::Ae),
        &reporter,
    )?;
    let (library, objects_label) = library(robot, 5, args.object_seed, &reporter)?;
    let mut recognizer = recognizer(&args, &library, &reporter)?;
    let set: Vec<ObjectModel> = interleaved_order(&library)
        .into_iter()
        .take(args.objects)
        .map(|i| library[i].clone())
        .collect();
    if set.len() < args.objects {
        reporter.message(&format!(
            "note: --objects {}: the library holds {} objects; using them all",
            args.objects,
            set.len()
        ));
    }
    // With only --attempts, every round has at least one attempt: that many rounds suffice.
    let default_rounds = if targets.is_some() { 50 } else { 10 };
    let rounds = args.rounds.or(args.attempts).unwrap_or(default_rounds);
    let label = format!(
        "{objects_label}, {} objects: {}",
        set.len(),
        set.iter()
            .map(|o| o.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut spec = run_spec(robot, scenario, rounds, args.seed, label);
    spec.max_attempts = args.attempts;
    check_library(&spec.config.world, &set).context("the object library")?;
    // Targets and the arrival plan are checked before the run directory is touched.
    if let Some(targets) = targets {
        let packing = PackingSpec::new(targets);
        let known = known_categories(&set, recognizer.labels());
        packing
            .validate(&known, &spec.config.world)
            .context("--targets")?;
        spec.packing = Some(packing);
    }
    if let Some(k) = args.arrive_after {
        let arrival = Arrival::split(&set, k).with_context(|| format!("--arrive-after {k}"))?;
        arrival
            .validate(rounds)
            .with_context(|| format!("--arrive-after {k}"))?;
        spec.arrival = Some(arrival);
    }
    let record = record_config(robot);
    let mut run_dir = SimRunDir::create(&robot.out, robot.force)?;
    let started = Instant::now();
    let (total, unit) = match args.attempts {
        Some(n) => (n as u64, "attempts"),
        None => (rounds as u64, "rounds"),
    };
    let mut task = reporter.bar(command, total);
    let progress = |p: &RunProgress| {
        let done = if args.attempts.is_some() {
            p.attempts
        } else {
            p.rounds_done
        };
        task.update_coarse(unit, done as u64, total);
    };
    let results = run_pick_place(
        &spec,
        &set,
        source.as_mut(),
        &mut recognizer,
        progress,
        record
            .as_ref()
            .map(|c| (c, &mut run_dir as &mut dyn lgdm_sim::record::RoundSink)),
    );
    task.finish();
    let results = results.with_context(|| format!("running {command}"))?;
    run_dir.write_results(&results)?;
    let (gdm, labels) = recognizer.into_parts();
    gdm.save(&run_dir.path().join(MODEL_FILE))
        .context("saving the model")?;
    let model_record = ModelRecord {
        encoder: args.encoder.name().to_string(),
        categories: labels.categories,
        instances: labels.instances,
    };
    run_dir.write_file(
        MODEL_LABELS_FILE,
        (serde_json::to_string_pretty(&model_record)? + "\n").as_bytes(),
    )?;
    let table = pick_place_table(&results);
    run_dir.write_file("summary.txt", table.as_bytes())?;
    write_plots(&run_dir, &results).context("drawing the plots")?;
    write_learning_plots(&run_dir, &results).context("drawing the learning curve")?;
    write_packing_plots(&run_dir, &results).context("drawing the packing plots")?;
    let s = &results.summary;
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": robot.out.display().to_string(),
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
    print_end(robot, &table, record.is_some());
    Ok(())
}

/// The failure reasons that occurred, as `reason n, reason n` (`none` when none did).
fn failure_list(reasons: &std::collections::BTreeMap<String, usize>) -> String {
    let failures: Vec<String> = reasons
        .iter()
        .filter(|(_, n)| **n > 0)
        .map(|(k, n)| format!("{k} {n}"))
        .collect();
    if failures.is_empty() {
        "none".to_string()
    } else {
        failures.join(", ")
    }
}

/// The end of a run on the terminal (not with `--progress jsonl`): the summary table, where the
/// recorded rounds are, the run directory.
fn print_end(robot: &RobotArgs, table: &str, recorded: bool) {
    if robot.progress == ProgressMode::Jsonl {
        return;
    }
    println!("{table}");
    if recorded {
        println!(
            "recorded rounds (MCAP for Foxglove, PNG storyboards) in {}",
            robot.out.join(ROUNDS_DIR).display()
        );
    }
    println!("wrote {}", robot.out.display());
}

/// The pick-and-place summary: packing (in a packing run) and the end-of-run evaluation (with
/// categories arriving over time) first, then recognition and teacher, then the grasp run's
/// table.
pub fn pick_place_table(r: &RunResults) -> String {
    use std::fmt::Write;
    let s = &r.summary;
    let mut out = String::new();
    if let (Some(spec), Some(p)) = (&r.run.packing, &s.packing) {
        let _ = writeln!(
            out,
            "sim packing: {} → {} basket, everything else → {} basket",
            spec.targets.join(", "),
            basket_name(spec.target_basket),
            basket_name(spec.other_basket)
        );
        let _ = writeln!(out, "{:<28} rate (95 % Wilson interval, n)", "");
        let _ = writeln!(
            out,
            "{:<28} {}",
            "packing success (attempts)",
            p.success_rate.describe()
        );
        let _ = writeln!(
            out,
            "{:<28} {}",
            "objects packed correctly",
            p.packed_fraction.describe()
        );
        let _ = writeln!(
            out,
            "{:<28} {}",
            "objects cleared",
            s.cleared_fraction.describe()
        );
        let _ = writeln!(
            out,
            "failures by cause: {}",
            failure_list(&s.failure_reasons)
        );
        let decided: Vec<String> = p
            .decided_by
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        let _ = writeln!(out, "baskets chosen by: {}\n", decided.join(", "));
    }
    if let Some(e) = &r.arrival_evaluation {
        let a = &e.arrival;
        let _ = writeln!(
            out,
            "categories arriving over time: {} before round {}, {} from it on",
            a.early_categories.join(", "),
            a.after_round,
            a.late_categories.join(", ")
        );
        for (when, ev) in [
            ("when the late categories arrived", e.at_switch.as_ref()),
            ("at the end", Some(&e.at_end)),
        ] {
            let Some(ev) = ev else { continue };
            let _ = writeln!(
                out,
                "first guess {when}, after {} rounds ({} fresh poses per object, no teacher):",
                ev.after_rounds, a.eval_poses
            );
            for (name, rate) in [
                ("early categories (category)", &ev.early_category_accuracy),
                ("early categories (instance)", &ev.early_instance_accuracy),
                (
                    "early, answer right (any conf.)",
                    &ev.early_category_answer_accuracy,
                ),
                ("late categories (category)", &ev.late_category_accuracy),
                ("late categories (instance)", &ev.late_instance_accuracy),
            ] {
                let _ = writeln!(out, "  {name:<32} {}", rate.describe());
            }
        }
        let _ = writeln!(out);
    }
    if let Some(rec) = &r.recognition {
        let _ = writeln!(
            out,
            "{}: {} encoder, start model {}, replay {}, learns {}",
            if r.run.packing.is_some() {
                "recognition"
            } else {
                "sim pick-place"
            },
            rec.encoder,
            rec.start_model,
            if rec.config.replay { "on" } else { "off" },
            if rec.config.learn_known {
                "every object"
            } else {
                "the teacher's lessons"
            }
        );
        let _ = writeln!(out, "{:<28} rate (95 % Wilson interval, n)", "");
        for (name, rate) in [
            ("recognition (category)", &s.recognition_accuracy),
            ("recognition (instance)", &s.instance_recognition_accuracy),
            ("teacher interventions", &s.teacher_intervention_rate),
        ] {
            if let Some(rate) = rate {
                let _ = writeln!(out, "{name:<28} {}", rate.describe());
            }
        }
        if let (Some(first), Some(last)) = (rec.memory.first(), rec.memory.last()) {
            let _ = writeln!(
                out,
                "nodes G-EM / G-SM            {} / {} at the start, {} / {} after {} rounds \
                 ({} lessons)",
                first.episodic_nodes,
                first.semantic_nodes,
                last.episodic_nodes,
                last.semantic_nodes,
                last.rounds,
                last.lessons
            );
        }
        let _ = writeln!(
            out,
            "replay at the rounds' ends {:.1} s, recognition {:.1} s\n",
            r.wall.replay_s, r.wall.attempts.recognition_s
        );
    }
    // The grasp table's first line names the command that made it.
    let grasp = summary_table(r);
    out.push_str(&grasp.replacen("sim grasp:", "grasp and placement:", 1));
    out
}

/// Packing: `packing_by_category.png` (success by the true category of the object aimed at,
/// Wilson 95 %). Categories arriving over time: `end_evaluation.png` (first-guess category
/// accuracy per category at the end, early and late marked).
fn write_packing_plots(dir: &SimRunDir, r: &RunResults) -> Result<()> {
    let bar = |label: String, rate: &lgdm_sim::run::Rate| Bar {
        label,
        value: rate.value.unwrap_or(0.0),
        interval: Some((rate.wilson_low, rate.wilson_high)),
    };
    if let (Some(spec), Some(p)) = (&r.run.packing, &r.summary.packing) {
        let bars: Vec<Bar> = p
            .per_category
            .iter()
            .map(|(c, rate)| {
                let side = if spec.targets.contains(c) { "R" } else { "L" };
                bar(format!("{c} ({side})"), rate)
            })
            .collect();
        write_bar_chart(
            &dir.path().join("packing_by_category.png"),
            &format!(
                "Packing success by category (R: {} basket, L: {}; Wilson 95 %)",
                basket_name(spec.target_basket),
                basket_name(spec.other_basket)
            ),
            "in its true category's basket",
            &bars,
            1.05,
        )?;
    }
    if let Some(e) = &r.arrival_evaluation {
        let (arrival, e) = (&e.arrival, &e.at_end);
        let mut categories: Vec<(String, bool)> = Vec::new();
        for l in &e.looks {
            if !categories.iter().any(|(c, _)| c == &l.category) {
                categories.push((l.category.clone(), l.early));
            }
        }
        let bars: Vec<Bar> = categories
            .iter()
            .map(|(c, early)| {
                let of: Vec<_> = e.looks.iter().filter(|l| &l.category == c).collect();
                let rate = lgdm_sim::run::Rate::new(
                    of.iter().filter(|l| l.category_correct).count(),
                    of.len(),
                );
                bar(
                    format!("{c} ({})", if *early { "early" } else { "late" }),
                    &rate,
                )
            })
            .collect();
        write_bar_chart(
            &dir.path().join("end_evaluation.png"),
            &format!(
                "First guess at the end, replay {} (late categories from round {})",
                r.recognition
                    .as_ref()
                    .map_or("?", |x| if x.config.replay { "on" } else { "off" }),
                arrival.after_round
            ),
            "category accuracy",
            &bars,
            1.05,
        )?;
    }
    Ok(())
}

/// `learning_curve.png` (first-guess accuracy and teacher interventions against objects seen,
/// over the last 25 recognitions and over all so far) and `nodes.png` (both memories' nodes
/// after each round).
fn write_learning_plots(dir: &SimRunDir, r: &RunResults) -> Result<()> {
    const WINDOW: usize = 25;
    let looks: Vec<&RecognitionRecord> = r
        .attempts
        .iter()
        .filter_map(|a| a.recognition.as_ref())
        .filter(|x| x.first_look)
        .collect();
    let windowed = |f: fn(&RecognitionRecord) -> bool| -> Vec<(f64, f64)> {
        (0..looks.len())
            .map(|i| {
                let from = (i + 1).saturating_sub(WINDOW);
                let part = &looks[from..=i];
                let k = part.iter().filter(|x| f(x)).count();
                ((i + 1) as f64, k as f64 / part.len() as f64)
            })
            .collect()
    };
    let cumulative = |f: fn(&RecognitionRecord) -> bool| -> Vec<(f64, f64)> {
        let mut k = 0;
        looks
            .iter()
            .enumerate()
            .map(|(i, x)| {
                k += usize::from(f(x));
                ((i + 1) as f64, k as f64 / (i + 1) as f64)
            })
            .collect()
    };
    write_lines(
        &dir.path().join("learning_curve.png"),
        "Recognition in the loop: first guess and teacher",
        "objects seen",
        "share",
        &[
            (
                format!("first-guess category accuracy (last {WINDOW})"),
                windowed(|x| x.category_correct),
            ),
            (
                format!("teacher interventions (last {WINDOW})"),
                windowed(|x| x.teacher),
            ),
            (
                "first-guess category accuracy (all so far)".into(),
                cumulative(|x| x.category_correct),
            ),
            (
                "teacher interventions (all so far)".into(),
                cumulative(|x| x.teacher),
            ),
        ],
        true,
    )?;
    if let Some(rec) = &r.recognition {
        let nodes = |f: fn(&MemoryPoint) -> usize| -> Vec<(f64, f64)> {
            rec.memory
                .iter()
                .map(|m| (m.objects_seen as f64, f(m) as f64))
                .collect()
        };
        write_lines(
            &dir.path().join("nodes.png"),
            "Nodes of the dual memory (after each round)",
            "objects seen",
            "nodes",
            &[
                ("G-EM".into(), nodes(|m| m.episodic_nodes)),
                ("G-SM".into(), nodes(|m| m.semantic_nodes)),
            ],
            false,
        )?;
    }
    Ok(())
}
