//! The robot's jobs as one library call each — what `lgdm sim grasp`, `lgdm sim pick-place` and
//! `lgdm sim packing` run, and what a Rust (or, through the Python module, a Python) caller
//! runs the same way:
//!
//! - [`GraspJob`]: rounds of a scenario with one grasp source.
//! - [`PickPlaceJob`]: the paper's pick-and-place with recognition in the loop, and with
//!   [`PickPlaceSetup::targets`] its packing.
//!
//! Each is prepared from a setup ([`GraspSetup`], [`PickPlaceSetup`]): the objects are built or
//! imported ([`crate::run::objects`]), the model to start from is read and checked against the
//! encoder, and every setting is validated, and every object the rounds will show has its collider
//! built — all before a grasp source or an encoder is loaded (the autoencoder's start torch) and
//! before the run directory is touched. [`GraspJob::run`] and [`PickPlaceJob::run`] then play the
//! run and, given an [`Output`], write the run directory the binary writes: `results.json`,
//! `summary.txt`, with recognition `model.lgdm` + `model.json` (which `--model`, `lgdm eval` and
//! `lgdm.GDM.load` read), with recording `rounds/round-NNNN.{mcap,png}`, and the plots
//! ([`crate::run::plots`]).
//!
//! ```no_run
//! use lgdm_sim::run::job::{Output, PickPlaceJob, PickPlaceSetup};
//! use lgdm_sim::recognition::encoder::GoodEncoder;
//! use lgdm_sim::grasping::source::AnalyticSource;
//! let setup = PickPlaceSetup {
//!     attempts: Some(20),
//!     out: Some(Output::new("runs/pp")),
//!     ..PickPlaceSetup::default()
//! };
//! let job = PickPlaceJob::prepare(setup).unwrap();
//! let results = job
//!     .run(&mut AnalyticSource::new(), Box::new(GoodEncoder), |_| {})
//!     .unwrap();
//! println!("{}", results.summary.placement_success_rate.describe());
//! ```

use std::path::{Path, PathBuf};

use lgdm_base::Progress;
use lgdm_pointcloud::objects::ObjectModel;
use serde::{Deserialize, Serialize};

use crate::grasping::source::GraspSource;
use crate::perception::camera::CameraConfig;
use crate::physics::shapes::LibraryShapes;
use crate::recognition::config::RecognitionConfig;
use crate::recognition::encoder::ViewEncoder;
use crate::recognition::error::RecognitionError;
use crate::recognition::labels::Labels;
use crate::recognition::model::StartModel;
use crate::recognition::recognizer::Recognizer;
use crate::run::config::SimConfig;
use crate::run::error::{SimError, setting};
use crate::run::objects::{ObjectLibrary, ObjectSource};
use crate::run::observe::RunObserver;
use crate::run::record::{RecordConfig, RoundRecorder};
use crate::run::results::RunResults;
use crate::run::run_dir::{Checkpoint, SimRunDir};
use crate::run::runner::{play, prepare_shapes};
use crate::run::spec::RunSpec;
use crate::run::state::RunState;
use crate::tasks::arrival::Arrival;
use crate::tasks::packing::PackingSpec;
use crate::tasks::scenario::{Scenario, interleaved_order};

/// Where a job writes its run directory.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Output {
    /// The run directory (new or empty).
    pub dir: PathBuf,
    /// Replace a previous sim run in it (its files are removed first; anything else is never
    /// touched).
    pub force: bool,
}

impl Output {
    /// `dir`, not replacing anything.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            force: false,
        }
    }
}

/// What `lgdm sim grasp` takes. Defaults are the binary's.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GraspSetup {
    /// The scenario (default isolated).
    pub scenario: Scenario,
    /// Rounds to play (default 10).
    pub rounds: usize,
    /// Base seed: object poses, clutter draws, the random source and the procedural instances
    /// (default 0).
    pub seed: u64,
    /// The objects (default: the procedural objects, 5 per category, built from `seed`).
    pub objects: Option<ObjectSource>,
    /// Every constant.
    pub config: SimConfig,
    /// Record the rounds (default none).
    pub record: Option<RecordConfig>,
    /// The run directory (none: results only). Not part of the job's record.
    #[serde(skip)]
    pub out: Option<Output>,
    /// Where the caller's network source came from, recorded in the job's record so that a
    /// resumed run can load it again (the library does not load it).
    #[serde(default)]
    pub ae_checkpoint: Option<PathBuf>,
}

impl Default for GraspSetup {
    fn default() -> Self {
        Self {
            scenario: Scenario::Isolated,
            rounds: 10,
            seed: 0,
            objects: None,
            config: SimConfig::default(),
            record: None,
            out: None,
            ae_checkpoint: None,
        }
    }
}

/// A checked grasp run, ready to play.
#[derive(Debug)]
pub struct GraspJob {
    setup: GraspSetup,
    stop: StopToken,
    spec: RunSpec,
    library: ObjectLibrary,
    shapes: LibraryShapes,
    record: Option<RecordConfig>,
    out: Option<Output>,
}

impl GraspJob {
    /// Builds the objects and checks everything (see the module docs).
    pub fn prepare(setup: GraspSetup) -> Result<GraspJob, SimError> {
        let kept = setup.clone();
        if setup.rounds == 0 {
            return Err(setting("rounds", 0, "at least one round is needed"));
        }
        let objects = setup.objects.unwrap_or(ObjectSource::Procedural {
            instances: 5,
            seed: setup.seed,
        });
        let library = objects.load()?;
        let mut spec = RunSpec::new(setup.scenario, setup.rounds, setup.seed);
        spec.objects = library.label.clone();
        spec.config = setup.config;
        check_record(setup.record.as_ref(), setup.out.as_ref())?;
        if let ObjectSource::Meshes { dir, .. } = &objects {
            check_inputs(setup.out.as_ref(), &[("meshes", dir)])?;
        }
        let shapes = prepare_shapes(&spec, &library.objects, None)?;
        Ok(GraspJob {
            setup: kept,
            stop: StopToken::default(),
            spec,
            library,
            shapes,
            record: setup.record,
            out: setup.out,
        })
    }

    /// The run it will play.
    pub fn spec(&self) -> &RunSpec {
        &self.spec
    }

    /// Its objects.
    pub fn library(&self) -> &ObjectLibrary {
        &self.library
    }

    /// Stops the run after its current round ([`StopToken`]).
    pub fn stop_token(&self) -> StopToken {
        self.stop.clone()
    }

    /// Plays the run with `source` and writes the run directory (when the setup has one): the
    /// job's record first, a checkpoint after every round, the results at the end.
    pub fn run(
        &self,
        source: &mut dyn GraspSource,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        let dir = open(self.out.as_ref())?;
        if let Some(d) = &dir {
            d.write_job(&JobRecord::new(
                source,
                JobKind::Grasp(Box::new(self.setup.clone())),
            ))?;
            d.write_config(&self.setup.config)?;
        }
        self.play_into(dir, source, None, on_progress)
    }

    /// Finishes the interrupted run in the setup's run directory (prepared from its
    /// [`JobRecord`], with `source` built as the record names it): the finished rounds are kept as
    /// they were written, and the results, recordings and files equal a run never stopped.
    pub fn resume(
        &self,
        source: &mut dyn GraspSource,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        let dir = reopen(self.out.as_ref(), source)?;
        let state = dir.read_checkpoint()?.map(|(c, _)| c.state);
        self.play_into(Some(dir), source, state, on_progress)
    }

    fn play_into(
        &self,
        mut dir: Option<SimRunDir>,
        source: &mut dyn GraspSource,
        state: Option<RunState>,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        let spec = &self.spec;
        let saver = dir.as_ref().map(SimRunDir::checkpointer);
        let stop = &self.stop;
        let checkpoint = &mut |s: &RunState, r: Option<&Recognizer>| {
            saver.as_ref().map_or(Ok(()), |c| c.save(s, r))?;
            if stop.is_stopped() {
                return Err(SimError::Stopped {
                    rounds_done: s.rounds_done,
                });
            }
            Ok(())
        };
        let cameras = &spec.config.cameras;
        let library = &self.library.objects;
        let results = observed(self.record.as_ref(), dir.as_mut(), cameras, |observer| {
            let shapes = Some(self.shapes.clone());
            play(
                spec,
                library,
                shapes,
                source,
                None,
                observer,
                on_progress,
                state,
                checkpoint,
            )
        })?;
        if let Some(dir) = &dir {
            dir.write_results(&results)?;
            dir.finish()?;
        }
        Ok(results)
    }
}

/// What a run directory's [`crate::run::run_dir::JOB_FILE`] holds: the job's setup and the grasp
/// source it ran with, so that `resume` can play it again.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JobRecord {
    /// [`JOB_FORMAT_VERSION`].
    pub format_version: u32,
    /// The grasp source's name (`analytic`, `random`, `network`).
    pub grasp_source: String,
    /// The job.
    pub job: JobKind,
}

/// Version of the job record's layout.
pub const JOB_FORMAT_VERSION: u32 = 1;

/// A job's kind and setup.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JobKind {
    /// `lgdm sim grasp`.
    Grasp(Box<GraspSetup>),
    /// `lgdm sim pick-place`, or with targets `lgdm sim packing`.
    PickPlace(Box<PickPlaceSetup>),
}

impl JobRecord {
    fn new(source: &dyn GraspSource, job: JobKind) -> Self {
        Self {
            format_version: JOB_FORMAT_VERSION,
            grasp_source: source.name().to_string(),
            job,
        }
    }

    /// The record of the run in `dir` (to prepare the job again and resume it).
    pub fn read(dir: &std::path::Path) -> Result<JobRecord, SimError> {
        let record: JobRecord = SimRunDir::read_job(dir)?;
        if record.format_version != JOB_FORMAT_VERSION {
            return Err(SimError::RunDir {
                path: dir.to_path_buf(),
                reason: format!(
                    "job record version {}, this lgdm reads version {JOB_FORMAT_VERSION}",
                    record.format_version
                ),
            });
        }
        Ok(record)
    }
}

/// The run directory of `out` reopened to resume (it must be there), for `source` — the one its
/// record names.
fn reopen(out: Option<&Output>, source: &dyn GraspSource) -> Result<SimRunDir, SimError> {
    let Some(out) = out else {
        return Err(setting("resume", "", "resuming needs the run directory"));
    };
    let dir = SimRunDir::reopen(&out.dir)?;
    let record = JobRecord::read(&out.dir)?;
    if record.grasp_source != source.name() {
        return Err(setting(
            "grasp",
            source.name(),
            format!(
                "the run in {} used {}",
                out.dir.display(),
                record.grasp_source
            ),
        ));
    }
    Ok(dir)
}

/// What `lgdm sim pick-place` and `lgdm sim packing` take. Defaults are the binary's.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PickPlaceSetup {
    /// The scenario: scattered (default; the paper's table), packed or pile — not isolated.
    pub scenario: Scenario,
    /// Rounds to play (5 objects each). Default: as many as `attempts` when that is given (each
    /// round has at least one attempt), else 10, or 50 for packing.
    pub rounds: Option<usize>,
    /// Stop after this many grasp attempts (750: the paper's shape).
    pub attempts: Option<usize>,
    /// Base seed: object poses, the rounds' draws, the random source, the views (default 0).
    pub seed: u64,
    /// The objects the set is taken from (default: the procedural objects of the embedded
    /// dataset, 5 per category, seed 0, so a model `lgdm train` made knows them).
    pub objects: ObjectSource,
    /// The object set: the first this many objects taken category by category in turn (the
    /// first instance of every category, then the second, …; default 15: the paper's set).
    pub set_size: usize,
    /// Start from this checkpoint (`lgdm train`'s `model-trial<t>.lgdm` or a pick-place run's
    /// `model.lgdm`; its label names from the record beside it) instead of an empty model.
    pub model: Option<PathBuf>,
    /// Recognition constants (replay, learning every object, the confidence threshold, …).
    pub recognition: RecognitionConfig,
    /// The encoder recognition will use: its name (`good`, `ae`) and feature dimension, checked
    /// against the model before the encoder is loaded (default GOOD).
    pub encoder: (String, usize),
    /// Packing: the target categories, packed into the right basket, everything else into the
    /// left one (none: pick-and-place, everything to the left basket).
    pub targets: Option<Vec<String>>,
    /// Categories arriving over time: the first half of the set's categories before this
    /// round, the rest from it on, and the end-of-run evaluation.
    pub arrive_after: Option<usize>,
    /// Every constant.
    pub config: SimConfig,
    /// Record the rounds (default none).
    pub record: Option<RecordConfig>,
    /// The run directory (none: results only, the model stays in memory). Not part of the
    /// job's record.
    #[serde(skip)]
    pub out: Option<Output>,
    /// Where the caller's network source or autoencoder encoder came from, recorded in the
    /// job's record so that a resumed run can load it again (the library does not load it).
    #[serde(default)]
    pub ae_checkpoint: Option<PathBuf>,
}

impl Default for PickPlaceSetup {
    fn default() -> Self {
        Self {
            scenario: Scenario::Scattered,
            rounds: None,
            attempts: None,
            seed: 0,
            objects: ObjectSource::default(),
            set_size: 15,
            model: None,
            recognition: RecognitionConfig::default(),
            encoder: (
                crate::recognition::encoder::ENCODER.to_string(),
                lgdm_pointcloud::cache::GOOD_DIM,
            ),
            targets: None,
            arrive_after: None,
            config: SimConfig::default(),
            record: None,
            out: None,
            ae_checkpoint: None,
        }
    }
}

/// A checked pick-and-place (or packing) run, ready to play.
#[derive(Debug)]
pub struct PickPlaceJob {
    setup: PickPlaceSetup,
    stop: StopToken,
    spec: RunSpec,
    library: ObjectLibrary,
    shapes: LibraryShapes,
    set: Vec<ObjectModel>,
    start: Option<StartModel>,
    labels: Labels,
    recognition: RecognitionConfig,
    encoder: (String, usize),
    record: Option<RecordConfig>,
    out: Option<Output>,
    notes: Vec<String>,
}

impl PickPlaceJob {
    /// Builds or imports the objects, reads and checks the model, checks everything (see the
    /// module docs).
    pub fn prepare(setup: PickPlaceSetup) -> Result<PickPlaceJob, SimError> {
        let kept = setup.clone();
        let packing = setup.targets.is_some();
        let job = if packing { "packing" } else { "pick-place" };
        if setup.rounds == Some(0) {
            return Err(setting("rounds", 0, "at least one round is needed"));
        }
        if setup.attempts == Some(0) {
            return Err(setting("attempts", 0, "at least one attempt is needed"));
        }
        if setup.set_size == 0 {
            return Err(setting(
                "objects",
                0,
                "the object set needs at least one object",
            ));
        }
        if setup.scenario == Scenario::Isolated {
            return Err(setting(
                "scenario",
                "isolated",
                format!("{job} sets 5 objects per round; use scattered, packed or pile"),
            ));
        }
        setup.recognition.validate()?;
        let targets = setup.targets.as_deref().map(parse_targets).transpose()?;
        let library = setup.objects.load()?;
        let mut notes = Vec::new();
        let (name, dim) = (&setup.encoder.0, setup.encoder.1);
        let (start, labels) = match &setup.model {
            None => (None, Labels::of_objects(&library.objects)),
            Some(path) => {
                let start = StartModel::load(path, name, dim)?;
                let labels = match &start.labels {
                    Some(l) => l.clone(),
                    None => {
                        notes.push(format!(
                            "note: no run record (metrics.json or model.json) beside {}: its \
                             encoder cannot be checked and its ids are taken as the dataset ids \
                             of the object library",
                            path.display()
                        ));
                        Labels::of_objects(&library.objects)
                    }
                };
                (Some(start), labels)
            }
        };
        let set: Vec<ObjectModel> = interleaved_order(&library.objects)
            .into_iter()
            .take(setup.set_size)
            .map(|i| library.objects[i].clone())
            .collect();
        if set.len() < setup.set_size {
            return Err(setting(
                "objects",
                setup.set_size,
                format!(
                    "the object set is taken from {} ({} objects); ask for at most that many",
                    library.label,
                    set.len()
                ),
            ));
        }
        let default_rounds = if packing { 50 } else { 10 };
        let by_attempts = setup.attempts.map(|a| a.min(crate::run::spec::MAX_ROUNDS));
        let rounds = setup.rounds.or(by_attempts).unwrap_or(default_rounds);
        let label = format!(
            "{}, {} objects: {}",
            library.label,
            set.len(),
            set.iter()
                .map(|o| o.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let mut spec = RunSpec::new(setup.scenario, rounds, setup.seed);
        spec.objects = label;
        spec.config = setup.config;
        spec.max_attempts = setup.attempts;
        if let Some(targets) = targets {
            // Named as the option they come from; [`RunSpec::validate`] checks them again.
            let packing = PackingSpec::new(targets);
            let known = crate::tasks::packing::known_categories(&set, &labels);
            let all = packing.targets.join(",");
            packing
                .validate(&known, &spec.config.world)
                .map_err(|e| setting("targets", &all, e))?;
            // A target no object of the set belongs to would never be met: its packing rate
            // would be about the other objects only.
            if let Some(absent) = packing
                .targets
                .iter()
                .find(|t| !set.iter().any(|o| &o.category == *t))
            {
                let mut in_set: Vec<&str> = Vec::new();
                for o in &set {
                    if !in_set.contains(&o.category.as_str()) {
                        in_set.push(&o.category);
                    }
                }
                return Err(setting(
                    "targets",
                    &all,
                    format!(
                        "no object of the set is a {absent} (the set's categories: {}); \
                         give --objects so the set holds one, or other targets",
                        in_set.join(", ")
                    ),
                ));
            }
            spec.packing = Some(packing);
        }
        if let Some(k) = setup.arrive_after {
            let arrival = Arrival::split(&set, k)
                .and_then(|a| a.validate(rounds).map(|()| a))
                .map_err(|e| setting("arrive-after", k, e))?;
            spec.arrival = Some(arrival);
        }
        check_record(setup.record.as_ref(), setup.out.as_ref())?;
        let mut inputs: Vec<(&'static str, &Path)> = Vec::new();
        if let Some(model) = &setup.model {
            inputs.push(("model", model));
        }
        if let ObjectSource::Meshes { dir, .. } = &setup.objects {
            inputs.push(("meshes", dir));
        }
        check_inputs(setup.out.as_ref(), &inputs)?;
        let shapes = prepare_shapes(&spec, &set, Some(&labels))?;
        Ok(PickPlaceJob {
            setup: kept,
            stop: StopToken::default(),
            spec,
            library,
            shapes,
            set,
            start,
            labels,
            recognition: setup.recognition,
            encoder: setup.encoder,
            record: setup.record,
            out: setup.out,
            notes,
        })
    }

    /// The run it will play.
    pub fn spec(&self) -> &RunSpec {
        &self.spec
    }

    /// Its objects (the library the set is taken from).
    pub fn library(&self) -> &ObjectLibrary {
        &self.library
    }

    /// The object set.
    pub fn set(&self) -> &[ObjectModel] {
        &self.set
    }

    /// Stops the run after its current round ([`StopToken`]).
    pub fn stop_token(&self) -> StopToken {
        self.stop.clone()
    }

    /// What the user should know about the setup (a model without a record beside it, a set
    /// larger than the library).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Plays the run with `source`, recognising with `encoder` (the one the setup named), and
    /// writes the run directory with the learnt model (when the setup has one). Returns the
    /// results; the learnt model is in the run directory.
    pub fn run(
        self,
        source: &mut dyn GraspSource,
        encoder: Box<dyn ViewEncoder>,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        self.run_keeping_model(source, encoder, on_progress)
            .map(|(results, _)| results)
    }

    /// [`PickPlaceJob::run`], also returning the recognizer with the model it learnt.
    pub fn run_keeping_model(
        self,
        source: &mut dyn GraspSource,
        encoder: Box<dyn ViewEncoder>,
        on_progress: impl FnMut(Progress),
    ) -> Result<(RunResults, Recognizer), SimError> {
        self.check_encoder(encoder.as_ref())?;
        let dir = open(self.out.as_ref())?;
        if let Some(d) = &dir {
            d.write_job(&JobRecord::new(
                source,
                JobKind::PickPlace(Box::new(self.setup.clone())),
            ))?;
            d.write_config(&self.setup.config)?;
        }
        self.play_into(dir, source, encoder, None, on_progress)
    }

    /// Finishes the interrupted run in the setup's run directory (prepared from its
    /// [`JobRecord`], with `source` and `encoder` built as the record names them): from the model
    /// and state its last finished round left, so the results, model and recordings equal a run
    /// never stopped.
    pub fn resume(
        self,
        source: &mut dyn GraspSource,
        encoder: Box<dyn ViewEncoder>,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        self.check_encoder(encoder.as_ref())?;
        let dir = reopen(self.out.as_ref(), source)?;
        let checkpoint = dir.read_checkpoint()?;
        self.play_into(Some(dir), source, encoder, checkpoint, on_progress)
            .map(|(results, _)| results)
    }

    fn check_encoder(&self, encoder: &dyn ViewEncoder) -> Result<(), SimError> {
        if encoder.name() != self.encoder.0 || encoder.dim() != self.encoder.1 {
            return Err(SimError::Recognition(RecognitionError::InvalidConfig {
                field: "encoder",
                reason: format!(
                    "the job was prepared for the `{}` encoder ({}-d), given `{}` ({}-d)",
                    self.encoder.0,
                    self.encoder.1,
                    encoder.name(),
                    encoder.dim()
                ),
            }));
        }
        Ok(())
    }

    fn play_into(
        self,
        mut dir: Option<SimRunDir>,
        source: &mut dyn GraspSource,
        encoder: Box<dyn ViewEncoder>,
        checkpoint: Option<(Checkpoint, Option<lgdm_gdm::Gdm>)>,
        on_progress: impl FnMut(Progress),
    ) -> Result<(RunResults, Recognizer), SimError> {
        let seed = self.spec.seed;
        let config = self.recognition;
        let (recognizer, state) = match (checkpoint, self.start) {
            (Some((c, Some(gdm))), _) => {
                let (Some(labels), Some(r)) = (c.labels, &c.state.recognizer) else {
                    return Err(SimError::Recognition(RecognitionError::InvalidConfig {
                        field: "progress",
                        reason: "the checkpoint has a model but no recognizer state".into(),
                    }));
                };
                let recognizer = Recognizer::restore(config, encoder, gdm, labels, seed, r)?;
                (recognizer, Some(c.state))
            }
            (_, None) => (
                Recognizer::empty_with_encoder(config, encoder, self.labels, seed)?,
                None,
            ),
            (_, Some(start)) => {
                let origin = start.path.display().to_string();
                let r = Recognizer::with_encoder(config, encoder, start.gdm, self.labels, seed)?;
                (r.with_origin(origin), None)
            }
        };
        // The views go through the cameras' sensor model, as the robot's other frames do.
        let mut recognizer = recognizer.with_sensor(self.spec.config.cameras.noise.clone());
        let (spec, set) = (&self.spec, &self.set);
        let saver = dir.as_ref().map(SimRunDir::checkpointer);
        let stop = &self.stop;
        let checkpoint = &mut |s: &RunState, r: Option<&Recognizer>| {
            saver.as_ref().map_or(Ok(()), |c| c.save(s, r))?;
            if stop.is_stopped() {
                return Err(SimError::Stopped {
                    rounds_done: s.rounds_done,
                });
            }
            Ok(())
        };
        let cameras = &spec.config.cameras;
        let shapes = Some(self.shapes);
        let recognizer_ref = Some(&mut recognizer);
        let results = observed(self.record.as_ref(), dir.as_mut(), cameras, |observer| {
            play(
                spec,
                set,
                shapes,
                source,
                recognizer_ref,
                observer,
                on_progress,
                state,
                checkpoint,
            )
        })?;
        if let Some(dir) = &dir {
            dir.write_results(&results)?;
            dir.write_model(&recognizer)?;
            dir.finish()?;
        }
        Ok((results, recognizer))
    }
}

/// Packing targets: trimmed, duplicates dropped (first kept), none empty.
fn parse_targets(targets: &[String]) -> Result<Vec<String>, SimError> {
    let mut out: Vec<String> = Vec::new();
    for t in targets {
        let t = t.trim();
        if t.is_empty() {
            return Err(setting(
                "targets",
                "",
                "an empty category name (give e.g. mug,can)",
            ));
        }
        if !out.iter().any(|o| o == t) {
            out.push(t.to_string());
        }
    }
    if out.is_empty() {
        return Err(setting(
            "targets",
            "",
            "no category given (give e.g. mug,can)",
        ));
    }
    Ok(out)
}

/// The run directory of `out`, claimed (none without one).
fn open(out: Option<&Output>) -> Result<Option<SimRunDir>, SimError> {
    out.map(|o| SimRunDir::create(&o.dir, o.force)).transpose()
}

/// A run never writes over its own inputs: `out` must not be, or hold, any of `inputs` (a
/// `--model` inside the run directory would be replaced by the run's own model, and with
/// `force` the results beside it removed first).
fn check_inputs(out: Option<&Output>, inputs: &[(&'static str, &Path)]) -> Result<(), SimError> {
    let Some(out) = out else {
        return Ok(());
    };
    let resolve = |p: &Path| -> PathBuf {
        // The deepest existing ancestor, resolved (symlinks, `..`), with the rest appended.
        let mut existing = p.to_path_buf();
        let mut rest = Vec::new();
        while !existing.exists() {
            match (
                existing.file_name().map(|n| n.to_os_string()),
                existing.parent(),
            ) {
                (Some(name), Some(parent)) => {
                    rest.push(name);
                    existing = parent.to_path_buf();
                }
                _ => break,
            }
        }
        let base = if existing.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            existing
        };
        let mut full = std::fs::canonicalize(&base).unwrap_or(base);
        full.extend(rest.iter().rev());
        full
    };
    let dir = resolve(&out.dir);
    for (name, input) in inputs {
        let input_path = resolve(input);
        if input_path.starts_with(&dir) {
            return Err(setting(
                name,
                input.display(),
                format!(
                    "it is in the run directory {}, which the run writes (and with --force \
                     clears first): choose another --out",
                    out.dir.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Recording needs a run directory to write the rounds to.
fn check_record(record: Option<&RecordConfig>, out: Option<&Output>) -> Result<(), SimError> {
    if let Some(r) = record {
        r.validate()?;
        if out.is_none() {
            return Err(setting(
                "record",
                "on",
                "recording writes the rounds into the run directory: give one",
            ));
        }
    }
    Ok(())
}

/// Runs `play` with the run's observer: the rounds recorded into `dir` when `record` is set,
/// else nothing.
fn observed<T>(
    record: Option<&RecordConfig>,
    dir: Option<&mut SimRunDir>,
    cameras: &CameraConfig,
    play: impl FnOnce(&mut dyn RunObserver) -> Result<T, SimError>,
) -> Result<T, SimError> {
    match (record, dir) {
        (Some(config), Some(dir)) => {
            let mut recorder = RoundRecorder::new(config, dir, cameras.clone())?;
            play(&mut recorder)
        }
        _ => play(&mut ()),
    }
}

/// Asks a running job to stop: it finishes the round it is playing, writes that round's
/// checkpoint and returns [`SimError::Stopped`] — nothing half-written, and `resume` plays the
/// rest. Clones share the request (a signal handler or another thread holds one).
#[derive(Debug, Clone, Default)]
pub struct StopToken(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl StopToken {
    /// Asks the job to stop after its current round.
    pub fn stop(&self) {
        self.0.store(true, std::sync::atomic::Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    pub fn is_stopped(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// The shared flag, for a signal handler that sets it (`signal_hook::flag::register`):
    /// setting it is [`StopToken::stop`].
    pub fn flag(&self) -> std::sync::Arc<std::sync::atomic::AtomicBool> {
        std::sync::Arc::clone(&self.0)
    }
}
