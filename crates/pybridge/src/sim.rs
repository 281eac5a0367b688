//! The robot from Python (`lgdm.sim`): the `lgdm-sim` library's jobs — what `lgdm sim grasp`,
//! `pick-place` and `packing` run — with the options named as the command line's, and grasp
//! sources written in Python.
//!
//! Each call prepares the job (objects built or imported, colliders, the config checked),
//! plays it with the GIL released and returns the results as `results.json`'s JSON text; with
//! `out` it writes the same run directory (job record, config, per-round checkpoints, results,
//! plots) as the command line.
//!
//! A grasp source may be a Python callable ([`CallableSource`]): it is called with the robot's
//! crop and returns its grasps in the decoders' convention (see `lgdm/sim.py`).

use std::path::PathBuf;

use lgdm_pointcloud::Progress;
use lgdm_pointcloud::grasp::decode::{
    DecodedGrasp, GraspDecodeParams, GraspMapsView, decode_grasps, wrap_angle,
};
use lgdm_pointcloud::import::MeshUnits;
use lgdm_sim::grasping::source::{GraspQuery, GraspSource, SourceError, builtin_source};
use lgdm_sim::recognition::config::RecognitionConfig;
use lgdm_sim::recognition::encoder::{EncoderError, GoodEncoder, ViewEncoder};
use lgdm_sim::run::config::{ConfigOverrides, OptionValue, SimConfig};
use lgdm_sim::run::error::SimError;
use lgdm_sim::run::job::{
    GraspJob, GraspSetup, JobKind, JobRecord, Output, PickPlaceJob, PickPlaceSetup, StopToken,
};
use lgdm_sim::run::objects::ObjectSource;
use lgdm_sim::run::record::RecordConfig;
use lgdm_sim::run::results::RunResults;
use lgdm_sim::tasks::scenario::Scenario;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

use crate::decode::{crop_from_input, decode_params};
use crate::errors::{self, Kind};

/// A grasp source that calls a Python callable with the robot's crop.
#[derive(Debug)]
pub struct CallableSource {
    callable: Py<PyAny>,
    name: String,
    /// The first exception the callable raised (or its answer's problem), raised again when
    /// the run stops.
    error: Option<PyErr>,
}

impl CallableSource {
    /// `callable`, named after its `__qualname__` (else its type's).
    pub fn new(callable: &Bound<'_, PyAny>) -> PyResult<Self> {
        let name = callable
            .getattr("__qualname__")
            .or_else(|_| callable.get_type().getattr("__qualname__"))
            .and_then(|n| n.extract::<String>())
            .unwrap_or_else(|_| "callable".to_string());
        Ok(Self {
            callable: callable.clone().unbind(),
            name: format!("python:{name}"),
            error: None,
        })
    }

    fn ask(&self, py: Python<'_>, query: &GraspQuery<'_>, k: usize) -> PyResult<Vec<DecodedGrasp>> {
        let crop = query.crop;
        let side = crop.size_px as usize;
        let rgb: Vec<u8> = crop.rgb.iter().flatten().copied().collect();
        let rgb = PyArray1::from_vec(py, rgb).reshape([side, side, 3])?;
        let depth = PyArray1::from_vec(py, crop.depth_m.clone()).reshape([side, side])?;
        let focal_px = query.intrinsics.fx / crop.window.image_px_per_map_px;
        let d = PyDict::new(py);
        d.set_item("rgb", rgb)?;
        d.set_item("depth", depth)?;
        d.set_item("focal_px", focal_px)?;
        d.set_item("table_depth_m", crop.table_depth_m)?;
        d.set_item("stroke_m", query.gripper.max_opening_m)?;
        d.set_item("finger_width_m", query.gripper.finger_width_m)?;
        d.set_item("max_grasps", k)?;
        d.set_item("decode", decode_dict(py, query.decode)?)?;
        let answer = self.callable.call1(py, (d,))?;
        let answer = answer.bind(py);
        let list = answer.cast::<PyList>().map_err(|_| {
            errors::input(format!(
                "returned {}, not a list of grasps",
                answer
                    .get_type()
                    .name()
                    .map_or("?".into(), |n| n.to_string())
            ))
        })?;
        // The jaw's extent across the opening when the callable does not say: the finger's
        // width at the table's depth.
        let jaw_default = query.gripper.finger_width_m * focal_px / crop.table_depth_m;
        let mut grasps = Vec::with_capacity(list.len().min(k));
        for (i, item) in list.iter().enumerate().take(k) {
            grasps.push(
                grasp_from(&item, jaw_default, crop.size_px)
                    .map_err(|e| errors::input(format!("grasp {i}: {}", e.value(py))))?,
            );
        }
        Ok(grasps)
    }
}

/// One grasp from its dict: `center_px` (x, y), `angle` (rad), `width_px`, optional `jaw_px`
/// and `quality`, each a number (not a bool) within what a grasp on a `crop_px` crop can mean;
/// an error names the field.
fn grasp_from(item: &Bound<'_, PyAny>, jaw_default: f32, crop_px: u32) -> PyResult<DecodedGrasp> {
    let d = item
        .cast::<PyDict>()
        .map_err(|_| errors::input("is not a dict"))?;
    let get = |key: &str| -> PyResult<Option<Bound<'_, PyAny>>> { d.get_item(key) };
    let need = |key: &str| -> PyResult<Bound<'_, PyAny>> {
        get(key)?.ok_or_else(|| errors::input(format!("has no `{key}`")))
    };
    let number = |key: &str, v: Bound<'_, PyAny>| -> PyResult<f32> {
        let x: f64 = v
            .extract()
            .map_err(|_| errors::input(format!("`{key}` is not a number")))?;
        if !x.is_finite() {
            return Err(errors::input(format!("`{key}` is {x}")));
        }
        Ok(x as f32)
    };
    // A bool is a Python int: refused where a number is meant.
    fn not_bool<'py>(key: &str, v: Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        if v.is_instance_of::<pyo3::types::PyBool>() {
            return Err(errors::input(format!("`{key}` is a bool, not a number")));
        }
        Ok(v)
    }
    let centre = need("center_px")?;
    let centre: Vec<Bound<'_, PyAny>> = centre
        .try_iter()
        .and_then(|items| items.collect())
        .map_err(|_| errors::input("`center_px` is not a pair of numbers"))?;
    let [cx, cy] = <[Bound<'_, PyAny>; 2]>::try_from(centre)
        .map_err(|_| errors::input("`center_px` is not a pair of numbers"))?;
    let x = number("center_px", not_bool("center_px", cx)?)?;
    let y = number("center_px", not_bool("center_px", cy)?)?;
    // What cannot be meant: a centre more than a crop away from it, an opening or a jaw wider
    // than the crop (or not positive), an angle beyond a few turns (lost precision).
    let side = crop_px as f32;
    if !(-side..=2.0 * side).contains(&x) || !(-side..=2.0 * side).contains(&y) {
        return Err(errors::input(format!(
            "`center_px` ({x}, {y}) is far outside the {crop_px}-px crop"
        )));
    }
    let positive = |key: &str, v: f32| -> PyResult<f32> {
        if v <= 0.0 || v > 4.0 * side {
            return Err(errors::input(format!(
                "`{key}` is {v} px (must be > 0 and at most {} px, four crops)",
                4.0 * side
            )));
        }
        Ok(v)
    };
    let width_px = positive(
        "width_px",
        number("width_px", not_bool("width_px", need("width_px")?)?)?,
    )?;
    let jaw_px = match get("jaw_px")? {
        Some(v) => positive("jaw_px", number("jaw_px", not_bool("jaw_px", v)?)?)?,
        None => jaw_default,
    };
    let quality = match get("quality")? {
        Some(v) => number("quality", not_bool("quality", v)?)?,
        None => 1.0,
    };
    let angle = number("angle", not_bool("angle", need("angle")?)?)?;
    if angle.abs() > 1e3 {
        return Err(errors::input(format!(
            "`angle` is {angle} rad (at most 1000 in size)"
        )));
    }
    Ok(DecodedGrasp {
        center_px: [x as f32, y as f32],
        angle: wrap_angle(angle),
        width_px,
        jaw_px,
        quality,
    })
}

impl GraspSource for CallableSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn grasps(
        &mut self,
        query: &GraspQuery<'_>,
        k: usize,
    ) -> Result<Vec<DecodedGrasp>, SourceError> {
        if self.error.is_some() {
            return Err(self.failed("it failed before"));
        }
        match Python::attach(|py| self.ask(py, query, k)) {
            Ok(grasps) => Ok(grasps),
            Err(e) => {
                let message = Python::attach(|py| e.value(py).to_string());
                self.error = Some(e);
                Err(self.failed(&message))
            }
        }
    }
}

impl CallableSource {
    fn failed(&self, message: &str) -> SourceError {
        SourceError::Failed {
            source_name: self.name.clone(),
            source: message.to_string().into(),
        }
    }
}

/// A view encoder that calls a Python callable with each view's point cloud.
#[derive(Debug)]
pub struct CallableEncoder {
    callable: Py<PyAny>,
    name: String,
    dim: usize,
    /// The first exception the callable raised (or its answer's problem), shared with the
    /// caller: the job owns the encoder.
    error: std::sync::Arc<std::sync::Mutex<Option<PyErr>>>,
}

impl CallableEncoder {
    /// `(callable, dim)`: named `python:<__qualname__>`.
    fn new(callable: &Bound<'_, PyAny>, dim: usize) -> PyResult<Self> {
        if !callable.is_callable() || dim == 0 {
            return Err(errors::new(
                Kind::Config,
                "encoder must be \"good\" or (callable, dim) with dim ≥ 1",
            ));
        }
        let name = CallableSource::new(callable)?.name;
        Ok(Self {
            callable: callable.clone().unbind(),
            name,
            dim,
            error: Default::default(),
        })
    }

    fn call(
        &self,
        py: Python<'_>,
        view: &lgdm_pointcloud::PointCloud,
    ) -> PyResult<Option<Vec<f32>>> {
        let n = view.points.len();
        let points: Vec<f32> = view.points.iter().flatten().copied().collect();
        let points = PyArray1::from_vec(py, points).reshape([n, 3])?;
        let colors = match &view.colors {
            Some(c) => {
                let c: Vec<u8> = c.iter().flatten().copied().collect();
                Some(PyArray1::from_vec(py, c).reshape([n, 3])?)
            }
            None => None,
        };
        let answer = self.callable.call1(py, (points, colors))?;
        let answer = answer.bind(py);
        if answer.is_none() {
            return Ok(None);
        }
        let feature: Vec<f32> = answer
            .call_method0("__array__")
            .and_then(|a| a.call_method1("ravel", ()))
            .and_then(|a| a.call_method1("tolist", ()))
            .and_then(|a| a.extract())
            .or_else(|_| answer.extract())
            .map_err(|_| errors::input("returned neither None nor a vector of numbers"))?;
        if feature.len() != self.dim {
            return Err(errors::input(format!(
                "returned {} values, not the {} it was declared with",
                feature.len(),
                self.dim
            )));
        }
        if feature.iter().any(|v| !v.is_finite()) {
            return Err(errors::input("returned a value that is not finite"));
        }
        Ok(Some(feature))
    }
}

impl ViewEncoder for CallableEncoder {
    fn name(&self) -> &str {
        &self.name
    }

    fn dim(&self) -> usize {
        self.dim
    }

    fn encode(
        &mut self,
        views: &[lgdm_pointcloud::PointCloud],
        _camera: &lgdm_pointcloud::render::Camera,
    ) -> Result<Vec<Option<Vec<f32>>>, EncoderError> {
        if self.error.lock().map_or(true, |e| e.is_some()) {
            return Err(format!("the encoder {} failed before", self.name).into());
        }
        let answer = Python::attach(|py| {
            views
                .iter()
                .map(|v| self.call(py, v))
                .collect::<PyResult<Vec<_>>>()
        });
        answer.map_err(|e| {
            let message = Python::attach(|py| e.value(py).to_string());
            if let Ok(mut slot) = self.error.lock() {
                *slot = Some(e);
            }
            format!("the encoder {}: {message}", self.name).into()
        })
    }
}

/// The grasp source `grasp` names (`analytic`, `random`) or is (a callable).
enum Source {
    Builtin(String),
    Callable(CallableSource),
}

impl Source {
    fn from_py(grasp: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(name) = grasp.extract::<String>() {
            return match name.as_str() {
                "analytic" | "random" => Ok(Source::Builtin(name)),
                "network" => Err(errors::new(
                    Kind::Config,
                    "grasp=\"network\" needs the autoencoder bridge, which this module is built \
                     without: run `lgdm sim … --grasp network`, or pass the network as a \
                     callable (see lgdm.sim)",
                )),
                other => Err(errors::new(
                    Kind::Config,
                    format!(
                        "unknown grasp source `{other}` (known: analytic, random, or a callable)"
                    ),
                )),
            };
        }
        if grasp.is_callable() {
            return Ok(Source::Callable(CallableSource::new(grasp)?));
        }
        Err(errors::new(
            Kind::Config,
            "grasp must be \"analytic\", \"random\" or a callable",
        ))
    }
}

/// Reports progress to an optional Python callable `(stage, done, total)`; its first exception
/// is kept and raised when the run ends.
struct Reporter {
    callback: Option<Py<PyAny>>,
    error: Option<PyErr>,
    /// Ctrl-C (or another signal's exception) seen at a progress report: the run is asked to
    /// stop after its round and the exception raised when it has.
    interrupt: Option<PyErr>,
    stop: StopToken,
}

impl Reporter {
    fn report(&mut self, p: Progress) {
        Python::attach(|py| {
            if self.interrupt.is_none()
                && let Err(e) = py.check_signals()
            {
                self.interrupt = Some(e);
                self.stop.stop();
            }
            let Some(cb) = &self.callback else { return };
            if self.error.is_none()
                && let Err(e) = cb.call1(py, (p.stage, p.done, p.total))
            {
                if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
                    self.interrupt.get_or_insert(e);
                    self.stop.stop();
                } else {
                    self.error = Some(e);
                }
            }
        });
    }
}

/// A sim error as the matching exception: bad settings and inputs are `ConfigError` /
/// `InputError`, the rest `LgdmError`.
fn sim_error(e: SimError) -> PyErr {
    let kind = match &e {
        SimError::Setting { .. } | SimError::UnknownSource(_) => Kind::Config,
        SimError::Objects(_) | SimError::EmptyLibrary => Kind::Input,
        _ => Kind::Lgdm,
    };
    let mut message = e.to_string();
    let mut cause = std::error::Error::source(&e);
    while let Some(c) = cause {
        message.push_str(&format!(": {c}"));
        cause = c.source();
    }
    errors::new(kind, message)
}

/// The run's objects: `meshes` (with `units`) or the procedural ones.
fn objects(
    meshes: Option<PathBuf>,
    units: &[String],
    procedural: ObjectSource,
) -> PyResult<ObjectSource> {
    let Some(dir) = meshes else {
        return Ok(procedural);
    };
    let units =
        MeshUnits::parse(units).map_err(|r| errors::new(Kind::Config, format!("units: {r}")))?;
    Ok(ObjectSource::Meshes { dir, units })
}

/// The config: `config`'s file with `gripper`, `draw`, `shapes`, `proposal_check` on top.
fn config(
    file: Option<PathBuf>,
    gripper: Option<&str>,
    draw: Option<&str>,
    shapes: Option<&str>,
    proposal_check: Option<&str>,
) -> PyResult<SimConfig> {
    fn parse<T: OptionValue>(word: Option<&str>) -> PyResult<Option<T>> {
        word.map(T::parse)
            .transpose()
            .map_err(|e| errors::new(Kind::Config, e))
    }
    let overrides = ConfigOverrides {
        gripper: parse(gripper)?,
        draw: parse(draw)?,
        shapes: parse(shapes)?,
        proposal_check: parse(proposal_check)?,
    };
    SimConfig::resolve(file.as_deref(), &overrides)
        .map_err(|e| errors::new(Kind::Config, format!("config {e}")))
}

fn record(record: bool, record_rounds: Option<usize>) -> Option<RecordConfig> {
    (record || record_rounds.is_some()).then(|| RecordConfig {
        first_rounds: record_rounds,
        ..RecordConfig::default()
    })
}

fn scenario(name: &str) -> PyResult<Scenario> {
    name.parse()
        .map_err(|e: lgdm_sim::tasks::scenario::UnknownScenario| {
            errors::new(Kind::Config, format!("scenario: {e}"))
        })
}

/// Plays `play` with the source `grasp` names, the GIL released; the callable's or the
/// progress callback's exception, if any, is raised with the run's error as its context.
fn play(
    py: Python<'_>,
    grasp: &Bound<'_, PyAny>,
    seed: u64,
    progress: Option<Py<PyAny>>,
    stop: StopToken,
    encoder_error: Option<(String, std::sync::Arc<std::sync::Mutex<Option<PyErr>>>)>,
    play: impl FnOnce(&mut dyn GraspSource, &mut dyn FnMut(Progress)) -> Result<RunResults, SimError>
    + Send,
) -> PyResult<String> {
    let mut source = Source::from_py(grasp)?;
    let mut reporter = Reporter {
        callback: progress,
        error: None,
        interrupt: None,
        stop,
    };
    let (result, source) = py.detach(|| {
        let mut report = |p: Progress| reporter.report(p);
        let result = match &mut source {
            Source::Builtin(name) => match builtin_source(name, seed) {
                Ok(mut s) => play(s.as_mut(), &mut report),
                Err(e) => Err(e.into()),
            },
            Source::Callable(c) => play(c, &mut report),
        };
        (result, source)
    });
    if let Some((name, e)) =
        encoder_error.and_then(|(name, cell)| Some((name, cell.lock().ok()?.take()?)))
    {
        let err = errors::new(
            Kind::Lgdm,
            format!("the view encoder {name} failed: {}", e.value(py)),
        );
        err.set_cause(py, Some(e));
        return Err(err);
    }
    if let Some(e) = reporter.interrupt {
        // The run stopped after a checkpointed round: `lgdm.sim.resume` plays the rest.
        return Err(e);
    }
    if let Source::Callable(c) = &source
        && let Some(e) = &c.error
        && e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py)
    {
        // Ctrl-C arrived while the callable ran: the run stopped there, its finished rounds
        // checkpointed.
        return Err(e.clone_ref(py));
    }
    if let Source::Callable(c) = source
        && let Some(e) = c.error
    {
        let err = errors::new(
            Kind::Lgdm,
            format!("the grasp callable {} failed: {}", c.name, e.value(py)),
        );
        err.set_cause(py, Some(e));
        return Err(err);
    }
    if let Some(e) = reporter.error {
        return Err(e);
    }
    let results = result.map_err(sim_error)?;
    serde_json::to_string(&results)
        .map_err(|e| errors::new(Kind::Internal, format!("results to JSON: {e}")))
}

/// `lgdm sim grasp`: returns results.json's text.
#[pyfunction]
#[pyo3(signature = (*, scenario_name, grasp, rounds, seed, instances, meshes, units, config_file,
    gripper, draw, shapes, proposal_check, out, force, record_all, record_rounds, progress))]
#[allow(clippy::too_many_arguments)]
pub fn sim_grasp(
    py: Python<'_>,
    scenario_name: &str,
    grasp: &Bound<'_, PyAny>,
    rounds: usize,
    seed: u64,
    instances: usize,
    meshes: Option<PathBuf>,
    units: Vec<String>,
    config_file: Option<PathBuf>,
    gripper: Option<&str>,
    draw: Option<&str>,
    shapes: Option<&str>,
    proposal_check: Option<&str>,
    out: Option<PathBuf>,
    force: bool,
    record_all: bool,
    record_rounds: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let setup = GraspSetup {
        scenario: scenario(scenario_name)?,
        rounds,
        seed,
        objects: Some(objects(
            meshes,
            &units,
            ObjectSource::Procedural { instances, seed },
        )?),
        config: config(config_file, gripper, draw, shapes, proposal_check)?,
        record: record(record_all, record_rounds),
        out: out.map(|dir| Output { dir, force }),
        ae_checkpoint: None,
    };
    let job = py.detach(|| GraspJob::prepare(setup)).map_err(sim_error)?;
    play(
        py,
        grasp,
        seed,
        progress,
        job.stop_token(),
        None,
        |source, report| job.run(source, report),
    )
}

/// `lgdm sim pick-place` (no `targets`) and `lgdm sim packing`: returns results.json's text.
#[pyfunction]
#[pyo3(signature = (*, scenario_name, grasp, rounds, attempts, seed, objects_n, object_seed,
    meshes, units, model, replay, learn_always, encoder, confidence, targets, arrive_after,
    config_file, gripper, draw, shapes, proposal_check, out, force, record_all, record_rounds, progress))]
#[allow(clippy::too_many_arguments)]
pub fn sim_pick_place(
    py: Python<'_>,
    scenario_name: &str,
    grasp: &Bound<'_, PyAny>,
    rounds: Option<usize>,
    attempts: Option<usize>,
    seed: u64,
    objects_n: usize,
    object_seed: u64,
    meshes: Option<PathBuf>,
    units: Vec<String>,
    model: Option<PathBuf>,
    replay: bool,
    learn_always: bool,
    encoder: &Bound<'_, PyAny>,
    confidence: Option<f64>,
    targets: Option<Vec<String>>,
    arrive_after: Option<usize>,
    config_file: Option<PathBuf>,
    gripper: Option<&str>,
    draw: Option<&str>,
    shapes: Option<&str>,
    proposal_check: Option<&str>,
    out: Option<PathBuf>,
    force: bool,
    record_all: bool,
    record_rounds: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let defaults = RecognitionConfig::default();
    let callable = match encoder.extract::<String>() {
        Ok(name) if name == GoodEncoder.name() => None,
        Ok(other) => {
            return Err(errors::new(
                Kind::Config,
                format!(
                    "encoder: `{other}` is not known here (\"good\", or (callable, dim); `ae` \
                     needs the command line's ae build)"
                ),
            ));
        }
        Err(_) => {
            let (callable, dim): (Bound<'_, PyAny>, usize) = encoder.extract().map_err(|_| {
                errors::new(Kind::Config, "encoder must be \"good\" or (callable, dim)")
            })?;
            Some(CallableEncoder::new(&callable, dim)?)
        }
    };
    let encoder_id = match &callable {
        Some(c) => (c.name.clone(), c.dim),
        None => (GoodEncoder.name().to_string(), GoodEncoder.dim()),
    };
    let encoder_error = callable.as_ref().map(|c| (c.name.clone(), c.error.clone()));
    let encoder: Box<dyn ViewEncoder + Send> = match callable {
        Some(c) => Box::new(c),
        None => Box::new(GoodEncoder),
    };
    let setup = PickPlaceSetup {
        scenario: scenario(scenario_name)?,
        rounds,
        attempts,
        seed,
        objects: objects(
            meshes,
            &units,
            ObjectSource::Procedural {
                instances: 5,
                seed: object_seed,
            },
        )?,
        set_size: objects_n,
        model,
        recognition: RecognitionConfig {
            replay,
            learn_known: learn_always,
            confidence_threshold: confidence.unwrap_or(defaults.confidence_threshold),
            ..defaults
        },
        encoder: encoder_id,
        targets,
        arrive_after,
        config: config(config_file, gripper, draw, shapes, proposal_check)?,
        record: record(record_all, record_rounds),
        out: out.map(|dir| Output { dir, force }),
        ae_checkpoint: None,
    };
    let job = py
        .detach(|| PickPlaceJob::prepare(setup))
        .map_err(sim_error)?;
    let stop = job.stop_token();
    play(
        py,
        grasp,
        seed,
        progress,
        stop,
        encoder_error,
        |source, report| job.run(source, encoder, report),
    )
}

/// Finishes the interrupted run in `run_dir` with its own settings (its `job.json`), as
/// `lgdm sim … --resume` does: returns results.json's text. `grasp` is the source the run
/// used — by default the one its record names; a Python callable must be passed again (the
/// same `__qualname__`).
#[pyfunction]
#[pyo3(signature = (run_dir, *, grasp, progress))]
pub fn sim_resume(
    py: Python<'_>,
    run_dir: PathBuf,
    grasp: Option<&Bound<'_, PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let record = JobRecord::read(&run_dir).map_err(sim_error)?;
    let recorded = PyString::new(py, &record.grasp_source).into_any();
    let grasp = match grasp {
        Some(g) => g.clone(),
        None if record.grasp_source.starts_with("python:") => {
            return Err(errors::new(
                Kind::Config,
                format!(
                    "the run in {} used the Python callable {}: pass it again as grasp=",
                    run_dir.display(),
                    record.grasp_source
                ),
            ));
        }
        None => recorded,
    };
    match record.job {
        JobKind::Grasp(mut setup) => {
            setup.out = Some(Output::new(&run_dir));
            let seed = setup.seed;
            let job = py.detach(|| GraspJob::prepare(*setup)).map_err(sim_error)?;
            play(
                py,
                &grasp,
                seed,
                progress,
                job.stop_token(),
                None,
                |source, report| job.resume(source, report),
            )
        }
        JobKind::PickPlace(mut setup) => {
            if setup.encoder.0 != GoodEncoder.name() {
                return Err(errors::new(
                    Kind::Config,
                    format!(
                        "the run in {} recognises with the `{}` encoder, which this module is \
                         built without: resume it with `lgdm sim … --resume`",
                        run_dir.display(),
                        setup.encoder.0
                    ),
                ));
            }
            setup.out = Some(Output::new(&run_dir));
            let seed = setup.seed;
            let job = py
                .detach(|| PickPlaceJob::prepare(*setup))
                .map_err(sim_error)?;
            play(
                py,
                &grasp,
                seed,
                progress,
                job.stop_token(),
                None,
                |source, report| job.resume(source, Box::new(GoodEncoder), report),
            )
        }
    }
}

/// The keys of a crop's `decode` dict: the run's `[attempt.decode]` settings the network
/// source decodes its maps with (the others, the jaw and the depth window, are not the maps').
const DECODE_KEYS: [&str; 4] = [
    "quality_threshold",
    "min_distance_px",
    "quality_sigma_px",
    "width_sigma_px",
];

/// A crop's `decode` dict: the run's decoder settings ([`DECODE_KEYS`]).
fn decode_dict<'py>(py: Python<'py>, p: &GraspDecodeParams) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(DECODE_KEYS[0], p.quality_threshold)?;
    d.set_item(DECODE_KEYS[1], p.min_distance_px)?;
    d.set_item(DECODE_KEYS[2], p.quality_sigma_px)?;
    d.set_item(DECODE_KEYS[3], p.width_sigma_px)?;
    Ok(d)
}

/// `params` with the settings of a `decode` dict ([`DECODE_KEYS`]; missing keys keep theirs).
fn with_decode_dict(
    mut params: GraspDecodeParams,
    decode: &Bound<'_, PyDict>,
) -> PyResult<GraspDecodeParams> {
    for (key, value) in decode.iter() {
        let key: String = key
            .extract()
            .map_err(|_| errors::input("decode: keys must be strings"))?;
        let number = || -> PyResult<f64> {
            let x: f64 = value
                .extract()
                .map_err(|_| errors::input(format!("decode: `{key}` is not a number")))?;
            if x.is_finite() && x >= 0.0 {
                Ok(x)
            } else {
                Err(errors::input(format!(
                    "decode: `{key}` is {x}, not a finite number ≥ 0"
                )))
            }
        };
        match key.as_str() {
            "quality_threshold" => params.quality_threshold = number()? as f32,
            "quality_sigma_px" => params.quality_sigma_px = number()? as f32,
            "width_sigma_px" => params.width_sigma_px = number()? as f32,
            "min_distance_px" => {
                params.min_distance_px = value.extract().map_err(|_| {
                    errors::input("decode: `min_distance_px` is not a non-negative integer")
                })?
            }
            other => {
                return Err(errors::input(format!(
                    "decode: unknown setting `{other}` (known: {})",
                    DECODE_KEYS.join(", ")
                )));
            }
        }
    }
    Ok(params)
}

/// The grasp autoencoder's maps — quality, cos 2θ, sin 2θ and width, each `(H, H)` float32 at
/// the network's input size — decoded as `python -m train_ae.evaluate` decodes them into at most
/// `num_grasps` grasps (best first) with the checkpoint's jaw (`jaw_side_fraction`; `None`:
/// half the opening), moved to the pixels of the `crop_px`-side crop the input was resized from
/// (default: the maps' own size). `decode` (a crop's `decode` dict: the run's
/// `[attempt.decode]`) replaces train_ae's threshold, peak window and smoothing. The dicts are
/// the grasp callables' convention (`lgdm.sim.decode_grasps`): a callable wrapping the network
/// with it gives the robot the grasps `--grasp network` gives, bit for bit.
#[pyfunction]
#[pyo3(signature = (quality, cos2t, sin2t, width, *, num_grasps = 1, jaw_side_fraction = None, crop_px = None, decode = None))]
#[allow(clippy::too_many_arguments)]
pub fn sim_decode_grasps<'py>(
    py: Python<'py>,
    quality: PyReadonlyArray2<'py, f32>,
    cos2t: PyReadonlyArray2<'py, f32>,
    sin2t: PyReadonlyArray2<'py, f32>,
    width: PyReadonlyArray2<'py, f32>,
    num_grasps: usize,
    jaw_side_fraction: Option<f32>,
    crop_px: Option<usize>,
    decode: Option<Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyList>> {
    let shape = quality.shape().to_vec();
    for (name, map) in [("cos2t", &cos2t), ("sin2t", &sin2t), ("width", &width)] {
        if map.shape() != shape.as_slice() {
            return Err(errors::input(format!(
                "{name} is {:?}, quality {shape:?}: the four maps have one shape",
                map.shape()
            )));
        }
    }
    let (rows, cols) = (shape[0], shape[1]);
    let (q, c, s, w) = (
        quality
            .as_slice()
            .map_err(|_| errors::input("quality is not contiguous"))?,
        cos2t
            .as_slice()
            .map_err(|_| errors::input("cos2t is not contiguous"))?,
        sin2t
            .as_slice()
            .map_err(|_| errors::input("sin2t is not contiguous"))?,
        width
            .as_slice()
            .map_err(|_| errors::input("width is not contiguous"))?,
    );
    let maps = GraspMapsView {
        rows,
        cols,
        quality: q,
        cos2t: c,
        sin2t: s,
        width: w,
    };
    if num_grasps == 0 {
        return Ok(PyList::empty(py));
    }
    let mut params = decode_params(jaw_side_fraction, num_grasps);
    if let Some(decode) = &decode {
        params = with_decode_dict(params, decode)?;
    }
    let grasps = decode_grasps(maps, &params).map_err(|e| errors::input(e.to_string()))?;
    let list = PyList::empty(py);
    for g in grasps {
        let g = match crop_px {
            Some(n) if rows == cols => crop_from_input(&g, n, rows),
            Some(_) => {
                return Err(errors::input(format!(
                    "crop_px: the maps are {rows} × {cols}, not square"
                )));
            }
            None => g,
        };
        let d = PyDict::new(py);
        d.set_item("center_px", (g.center_px[0], g.center_px[1]))?;
        d.set_item("angle", g.angle)?;
        d.set_item("width_px", g.width_px)?;
        d.set_item("jaw_px", g.jaw_px)?;
        d.set_item("quality", g.quality)?;
        list.append(d)?;
    }
    Ok(list)
}
