//! The robot's jobs as one library call each — what `lgdm sim grasp`, `lgdm sim pick-place` and
//! `lgdm sim packing` run, and what a Rust (or, through the Python module, a Python) caller
//! runs the same way:
//!
//! - [`GraspJob`]: rounds of a scenario with one grasp source.
//! - [`PickPlaceJob`]: the paper's pick-and-place with recognition in the loop, and with
//!   [`PickPlaceSetup::targets`] its packing.
//!
//! Each is prepared from a setup ([`GraspSetup`], [`PickPlaceSetup`]): the objects are built
//! or imported, the model to start from is read and checked against the encoder, and every
//! setting is validated, and every object the rounds will show has its collider built — all
//! before a grasp source or an encoder is loaded (the autoencoder's
//! start torch) and before the run directory is touched. [`GraspJob::run`] and
//! [`PickPlaceJob::run`] then play the run and, given an [`Output`], write the run directory
//! the binary writes: `results.json`, `summary.txt`, with recognition `model.lgdm` +
//! `model.json` (which `--model`, `lgdm eval` and `lgdm.GDM.load` read), with recording
//! `rounds/round-NNNN.{mcap,png}`. The binary adds only its plots.
//!
//! ```no_run
//! use lgdm_sim::job::{Output, PickPlaceJob, PickPlaceSetup};
//! use lgdm_sim::recognize::GoodEncoder;
//! use lgdm_sim::source::AnalyticSource;
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
use lgdm_pointcloud::import::{ImportReport, MeshUnits, load_mesh_library};
use lgdm_pointcloud::objects::{CATEGORIES, ObjectModel, procedural_library};

use crate::arrival::Arrival;
use crate::camera::CameraConfig;
use crate::config::SimConfig;
use crate::model::StartModel;
use crate::observe::RunObserver;
use crate::packing::PackingSpec;
use crate::recognize::{Labels, RecognitionConfig, RecognitionError, Recognizer, ViewEncoder};
use crate::record::{RecordConfig, RoundRecorder};
use crate::results::RunResults;
use crate::run_dir::SimRunDir;
use crate::runner::{play, prepare_shapes};
use crate::scenario::{Scenario, interleaved_order};
use crate::shapes::LibraryShapes;
use crate::source::GraspSource;
use crate::spec::{RunSpec, SimError};

/// Where a job's objects come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ObjectSource {
    /// The procedural objects: `instances` per category, built from `seed`.
    Procedural {
        /// Instances per category (at least 1).
        instances: usize,
        /// The generator's seed (0: the embedded dataset's).
        seed: u64,
    },
    /// The meshes of `dir` in the `gen-dataset` layout (`DIR/<category>/<instance>.{obj,stl,ply}`),
    /// in `units` (guessed from the size where not given).
    Meshes {
        /// The folder.
        dir: PathBuf,
        /// Their units.
        units: MeshUnits,
    },
}

impl Default for ObjectSource {
    /// The procedural objects of the embedded dataset: 5 per category, seed 0.
    fn default() -> Self {
        Self::Procedural {
            instances: 5,
            seed: 0,
        }
    }
}

/// The most procedural instances per category a job may build (10 categories: 1,000 objects,
/// ~50 MB of meshes).
pub const MAX_INSTANCES: usize = 100;

/// A job's objects.
#[derive(Debug, Clone)]
pub struct ObjectLibrary {
    /// The objects.
    pub objects: Vec<ObjectModel>,
    /// Where they came from, for the record (`procedural`, `meshes DIR`).
    pub label: String,
    /// Imported meshes: each file's unit and size (the binary prints them).
    pub imported: Vec<ImportReport>,
}

impl ObjectSource {
    /// Builds or imports the objects.
    pub fn load(&self) -> Result<ObjectLibrary, SimError> {
        match self {
            Self::Procedural { instances, seed } => {
                if *instances == 0 {
                    return Err(setting(
                        "instances",
                        0,
                        "at least one instance per category is needed",
                    ));
                }
                if *instances > MAX_INSTANCES {
                    return Err(setting(
                        "instances",
                        instances,
                        format!("at most {MAX_INSTANCES} instances per category"),
                    ));
                }
                let objects = procedural_library(&CATEGORIES, *instances, *seed)
                    .map_err(|e| SimError::Objects(e.to_string()))?;
                Ok(ObjectLibrary {
                    objects,
                    label: "procedural".into(),
                    imported: Vec::new(),
                })
            }
            Self::Meshes { dir, units } => {
                let imported = load_mesh_library(dir, units)
                    .map_err(|e| SimError::Objects(format!("--meshes {}: {e}", dir.display())))?;
                let reports = imported.iter().map(|i| i.report.clone()).collect();
                Ok(ObjectLibrary {
                    objects: imported.into_iter().map(|i| i.object).collect(),
                    label: format!("meshes {}", dir.display()),
                    imported: reports,
                })
            }
        }
    }
}

/// A setting of a job that cannot be used.
fn setting(name: &'static str, value: impl ToString, reason: impl ToString) -> SimError {
    SimError::Setting {
        name,
        value: value.to_string(),
        reason: reason.to_string(),
    }
}

/// Where a job writes its run directory.
#[derive(Debug, Clone, PartialEq, Eq)]
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
#[derive(Debug, Clone)]
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
    /// The run directory (none: results only).
    pub out: Option<Output>,
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
        }
    }
}

/// A checked grasp run, ready to play.
#[derive(Debug)]
pub struct GraspJob {
    spec: RunSpec,
    library: ObjectLibrary,
    shapes: LibraryShapes,
    record: Option<RecordConfig>,
    out: Option<Output>,
}

impl GraspJob {
    /// Builds the objects and checks everything (see the module docs).
    pub fn prepare(setup: GraspSetup) -> Result<GraspJob, SimError> {
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

    /// Plays the run with `source` and writes the run directory (when the setup has one).
    pub fn run(
        &self,
        source: &mut dyn GraspSource,
        on_progress: impl FnMut(Progress),
    ) -> Result<RunResults, SimError> {
        let mut dir = open(self.out.as_ref())?;
        let spec = &self.spec;
        let cameras = &spec.config.cameras;
        let results = observed(self.record.as_ref(), dir.as_mut(), cameras, |observer| {
            let shapes = Some(self.shapes.clone());
            play(
                spec,
                &self.library.objects,
                shapes,
                source,
                None,
                observer,
                on_progress,
            )
        })?;
        if let Some(dir) = &dir {
            dir.write_results(&results)?;
        }
        Ok(results)
    }
}

/// What `lgdm sim pick-place` and `lgdm sim packing` take. Defaults are the binary's.
#[derive(Debug, Clone)]
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
    /// The run directory (none: results only, the model stays in memory).
    pub out: Option<Output>,
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
                crate::recognize::ENCODER.to_string(),
                lgdm_pointcloud::cache::GOOD_DIM,
            ),
            targets: None,
            arrive_after: None,
            config: SimConfig::default(),
            record: None,
            out: None,
        }
    }
}

/// A checked pick-and-place (or packing) run, ready to play.
#[derive(Debug)]
pub struct PickPlaceJob {
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
        let by_attempts = setup.attempts.map(|a| a.min(crate::spec::MAX_ROUNDS));
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
            let known = crate::packing::known_categories(&set, &labels);
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
        let seed = self.spec.seed;
        let mut recognizer = match self.start {
            None => Recognizer::empty_with_encoder(self.recognition, encoder, self.labels, seed)?,
            Some(start) => {
                let origin = start.path.display().to_string();
                Recognizer::with_encoder(self.recognition, encoder, start.gdm, self.labels, seed)?
                    .with_origin(origin)
            }
        };
        let mut dir = open(self.out.as_ref())?;
        let (spec, set) = (&self.spec, &self.set);
        let cameras = &spec.config.cameras;
        let results = observed(self.record.as_ref(), dir.as_mut(), cameras, |observer| {
            let shapes = Some(self.shapes);
            play(
                spec,
                set,
                shapes,
                source,
                Some(&mut recognizer),
                observer,
                on_progress,
            )
        })?;
        if let Some(dir) = &dir {
            dir.write_results(&results)?;
            dir.write_model(&recognizer)?;
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
