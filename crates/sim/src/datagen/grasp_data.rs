//! `lgdm sim grasp-data`: grasp images from the robot's own world, labelled by physics.
//!
//! Scene `s` is a pure function of `(seed, s)`: a table (isolated with
//! [`GraspDataSetup::isolated_share`], else packed, pile or scattered, equally likely) set as the
//! robot's rounds set it, from the same objects; the overview camera and segmentation; up to
//! [`GraspDataSetup::views_per_scene`] of its objects seen close up exactly as the robot sees them
//! before a grasp (the same camera, crop and collider drawing), varied where the robot's world
//! varies ([`Randomise`]: the colours of the table and of each object, the close-up's height, depth
//! noise). On each view the analytic, the random and the rim source ([`RimSource`]: astride the
//! wall of an open object) propose grasps (asked as the robot asks
//! them, [`crate::grasping::proposals::ranked_grasps`]); each is planned as the robot plans it and
//! tried by a free gripper ([`crate::grasping::free_grasp`]), the objects put back at rest after
//! each. Every view becomes one image in the grasp-image layout `gen-dataset` writes and `train_ae`
//! reads (`NN/pcdNNNN{r.png,d.tiff,cpos.txt,cneg.txt}`, `index.json`): the grasps that held are its
//! positive rectangles, the others its negatives, and each image's index entry carries the outcome
//! of every rectangle ([`PhysicsLabels`]). `grasp-data.json` records the setup and the counts;
//! `grasp_preview.png` shows the first eight images with their rectangles (green: held, red:
//! failed).
//!
//! Scenes run in parallel; they are written in order, so the set does not depend on the
//! number of threads. Same seed, same bytes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use lgdm_base::Progress;
use lgdm_base::fs::{DirLock, Entry, Ownership};
use lgdm_base::seed::derive_seed;
use lgdm_base::stats::Rate;
use lgdm_pointcloud::grasp::cornell::draw_rectangles;
use lgdm_pointcloud::grasp::cornell::{
    GraspImageInfo, GraspIndex, GraspOutcome, INDEX_FILE, INDEX_FORMAT, MAX_IMAGES, PhysicsLabels,
    cornell_number, cornell_prefix, write_rectangles,
};
use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::image::{RgbImage, write_depth_tiff};
use lgdm_pointcloud::preview::GRASP_PREVIEW;
use lgdm_pointcloud::render::{LABEL_BACKGROUND, RgbdFrame};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::grasping::attempt::plan_grasp_for;
use crate::grasping::free_grasp::{FreeGrasp, try_grasp};
use crate::grasping::proposals::ranked_grasps;
use crate::grasping::rim::RimSource;
use crate::grasping::source::{AnalyticSource, GraspSource, RandomSource};
use crate::perception::{ObjectView, Perception, PerceptionError};
use crate::physics::shapes::LibraryShapes;
use crate::physics::world::World;
use crate::run::config::SimConfig;
use crate::run::error::SimError;
use crate::run::objects::{ObjectLibrary, ObjectSource};
use crate::run::spec::RunSpec;
use crate::tasks::scenario::{Scenario, round_objects, set_table};

/// Seed tags of a grasp-data set: a scene's table, a view's randomisation, a view's random
/// source.
const TAG_SCENE: u64 = 0x5133_0030;
const TAG_VIEW: u64 = 0x5133_0031;
const TAG_RANDOM: u64 = 0x5133_0033;

/// The record of how a set was made, beside its `index.json`.
pub const SETUP_FILE: &str = "grasp-data.json";

/// How the views vary from the robot's (each view draws its own; [`Randomise::none`] gives
/// exactly the robot's view).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Randomise {
    /// Each colour channel of the table and of each object is scaled by a factor drawn from
    /// [1 − x, 1 + x] (default 0.4).
    pub colour_gain: f32,
    /// The close-up camera's height above the table varies by up to ± this much (m; default
    /// 0.03 around the robot's 0.5).
    pub camera_height_m: f32,
    /// Depth noise: Gaussian, its standard deviation drawn from [0, x] per view (m; default
    /// 0.0015).
    pub depth_noise_m: f32,
}

impl Default for Randomise {
    fn default() -> Self {
        Self {
            colour_gain: 0.4,
            camera_height_m: 0.03,
            depth_noise_m: 0.0015,
        }
    }
}

impl Randomise {
    /// No randomisation: every view is the robot's.
    pub fn none() -> Self {
        Self {
            colour_gain: 0.0,
            camera_height_m: 0.0,
            depth_noise_m: 0.0,
        }
    }

    fn validate(&self) -> Result<(), SimError> {
        for (name, v, max) in [
            ("randomise.colour_gain", self.colour_gain, 1.0),
            ("randomise.camera_height_m", self.camera_height_m, 0.2),
            ("randomise.depth_noise_m", self.depth_noise_m, 0.02),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(setting(name, v, format!("must be in [0, {max}]")));
            }
        }
        Ok(())
    }
}

/// What `lgdm sim grasp-data` takes. Defaults are the binary's.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GraspDataSetup {
    /// Scenes to set (default 100).
    pub scenes: usize,
    /// Base seed: the tables, the views, the random source and the procedural instances
    /// (default 0).
    pub seed: u64,
    /// The objects (default: the procedural objects, 5 per category, built from `seed`).
    pub objects: Option<ObjectSource>,
    /// Share of scenes with one object on the table (default 0.5); the rest are packed, pile
    /// or scattered.
    pub isolated_share: f64,
    /// Objects seen close up per cluttered scene, largest first (default 2).
    pub views_per_scene: usize,
    /// The analytic source's grasps tried per view (default 6).
    pub analytic: usize,
    /// The random source's grasps tried per view (default 6).
    pub random: usize,
    /// The rim source's grasps tried per view (default 3; [`RimSource`]: astride the wall of an
    /// open object; none on a closed object standing alone). Absent from records written before
    /// it: 0.
    #[serde(default)]
    pub rim: usize,
    /// How views vary from the robot's.
    pub randomise: Randomise,
    /// Every constant of the robot's world (gripper, cameras, scenarios, attempt).
    pub config: SimConfig,
}

impl Default for GraspDataSetup {
    fn default() -> Self {
        Self {
            scenes: 100,
            seed: 0,
            objects: None,
            isolated_share: 0.5,
            views_per_scene: 2,
            analytic: 6,
            random: 6,
            rim: 3,
            randomise: Randomise::default(),
            config: SimConfig::default(),
        }
    }
}

fn setting(name: &'static str, value: impl ToString, reason: impl ToString) -> SimError {
    SimError::Setting {
        name,
        value: value.to_string(),
        reason: reason.to_string(),
    }
}

/// Tried and held grasps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Tally {
    /// Grasps tried.
    pub tried: usize,
    /// Grasps that held.
    pub held: usize,
}

impl Tally {
    fn add(&mut self, held: bool) {
        self.tried += 1;
        self.held += usize::from(held);
    }

    /// The share that held, with its Wilson interval.
    pub fn rate(&self) -> Rate {
        Rate::new(self.held, self.tried)
    }
}

/// What a set holds (deterministic: no wall times).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct GraspDataSummary {
    /// Scenes set.
    pub scenes: usize,
    /// Images written (views with an object and at least one grasp proposed).
    pub images: usize,
    /// Every grasp tried.
    pub all: Tally,
    /// Per source.
    pub by_source: BTreeMap<String, Tally>,
    /// Per table.
    pub by_scenario: BTreeMap<String, Tally>,
    /// Failures per reason.
    pub failures: BTreeMap<String, usize>,
    /// Grasps the robot's planner would refuse (a pad closing on air), and how many of those
    /// held.
    pub refused_by_planner: Tally,
    /// Simulated seconds of all the trials.
    pub sim_s: f64,
}

/// One view's image and its tried grasps.
struct ViewImage {
    rgb: Vec<[u8; 3]>,
    depth_m: Vec<f32>,
    size_px: usize,
    info: GraspImageInfo,
    positives: Vec<lgdm_pointcloud::grasp::GraspRectangle>,
    negatives: Vec<lgdm_pointcloud::grasp::GraspRectangle>,
}

/// One scene's views and the numbers of its trials.
struct SceneOutput {
    views: Vec<ViewImage>,
    summary: GraspDataSummary,
}

/// A checked grasp-data job, ready to run.
#[derive(Debug)]
pub struct GraspDataJob {
    setup: GraspDataSetup,
    library: ObjectLibrary,
    categories: Vec<String>,
    shapes: LibraryShapes,
}

impl GraspDataJob {
    /// Builds or imports the objects, checks the setup and decomposes every object's collider.
    pub fn prepare(setup: GraspDataSetup) -> Result<Self, SimError> {
        if setup.scenes == 0 {
            return Err(setting("scenes", 0, "at least one scene is needed"));
        }
        let views = setup.views_per_scene.max(1);
        if setup.scenes.saturating_mul(views) > MAX_IMAGES {
            return Err(setting(
                "scenes",
                setup.scenes,
                format!(
                    "a set holds at most {MAX_IMAGES} images ({views} per scene): at most {} scenes",
                    MAX_IMAGES / views
                ),
            ));
        }
        if setup.views_per_scene == 0 {
            return Err(setting("views-per-scene", 0, "at least one view is needed"));
        }
        if !(0.0..=1.0).contains(&setup.isolated_share) {
            return Err(setting(
                "isolated-share",
                setup.isolated_share,
                "must be in [0, 1]",
            ));
        }
        if setup.analytic + setup.random + setup.rim == 0 {
            return Err(setting(
                "analytic",
                0,
                "no grasp to try: ask the analytic, the random or the rim source for at least one",
            ));
        }
        setup.randomise.validate()?;
        let objects = setup.objects.clone().unwrap_or(ObjectSource::Procedural {
            instances: 5,
            seed: setup.seed,
        });
        let library = objects.load()?;
        let mut spec = RunSpec::new(Scenario::Isolated, 1, setup.seed);
        spec.config = setup.config.clone();
        spec.validate(&library.objects, None)?;
        // The colliders of every object a scene draws, decomposed ahead in parallel and each
        // built once in a scratch world.
        let used: Vec<usize> = (0..setup.scenes)
            .flat_map(|s| scene_table(&setup, &library.objects, s).1)
            .collect();
        let mut shapes = LibraryShapes::new(setup.config.shapes.clone(), library.objects.len());
        shapes.prepare(&library.objects, &used);
        shapes.check(&setup.config.world, &library.objects, &used)?;
        let mut categories: Vec<String> =
            library.objects.iter().map(|o| o.category.clone()).collect();
        categories.sort();
        categories.dedup();
        Ok(Self {
            setup,
            library,
            categories,
            shapes,
        })
    }

    /// Its objects.
    pub fn library(&self) -> &ObjectLibrary {
        &self.library
    }

    /// Sets the scenes (`jobs` at a time) and writes the set into `out` — a new or empty
    /// directory, or with `force` one holding only a previous set. `on_progress` is called on
    /// this thread as scenes finish (stage `scenes`).
    pub fn run(
        &self,
        out: &Path,
        force: bool,
        jobs: usize,
        mut on_progress: impl FnMut(Progress),
    ) -> Result<GraspDataSummary, SimError> {
        let _lock = claim(out, force)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(jobs.max(1))
            .build()
            .map_err(|e| setting("jobs", jobs, e))?;
        let total = self.setup.scenes;
        let mut summary = GraspDataSummary::default();
        let mut index = GraspIndex {
            format: INDEX_FORMAT.into(),
            crop: Some(self.setup.config.cameras.crop),
            finger_width_m: self.setup.config.robot.gripper.finger_width_m,
            jaw_side_fraction: Some(
                self.setup
                    .config
                    .cameras
                    .crop
                    .side_fraction(self.setup.config.robot.gripper.finger_width_m),
            ),
            images: Vec::new(),
        };
        let chunk = 4 * jobs.max(1);
        let mut tiles = Vec::new();
        on_progress(Progress {
            stage: "scenes",
            done: 0,
            total: total as u64,
        });
        for first in (0..total).step_by(chunk) {
            let scenes: Vec<usize> = (first..(first + chunk).min(total)).collect();
            let outputs = pool.install(|| {
                scenes
                    .par_iter()
                    .map(|&s| self.scene(s))
                    .collect::<Result<Vec<_>, _>>()
            })?;
            for output in outputs {
                for view in output.views {
                    let k = index.images.len();
                    if tiles.len() < PREVIEW_TILES {
                        tiles.push(preview_tile(&view));
                    }
                    index.images.push(write_view(out, k, view)?);
                }
                summary.merge(&output.summary);
            }
            let done = (first + chunk).min(total);
            on_progress(Progress {
                stage: "scenes",
                done: done as u64,
                total: total as u64,
            });
        }
        summary.scenes = total;
        summary.images = index.images.len();
        write_json(&out.join(INDEX_FILE), &index)?;
        write_preview(&out.join(GRASP_PREVIEW), &tiles)?;
        let record = serde_json::json!({
            "setup": &self.setup,
            "objects": &self.library.label,
            "summary": &summary,
        });
        write_json(&out.join(SETUP_FILE), &record)?;
        Ok(summary)
    }

    /// Scene `s`: the table, the views and every trial (see the module docs).
    fn scene(&self, s: usize) -> Result<SceneOutput, SimError> {
        let setup = &self.setup;
        let cfg = &setup.config;
        let lib = &self.library.objects;
        let (scenario, picks, mut rng) = scene_table(setup, lib, s);
        let mut world = World::new(cfg.world.clone())?;
        let mut shapes = self.shapes.clone();
        let placed = set_table(
            &mut world,
            scenario,
            lib,
            &mut shapes,
            &picks,
            &cfg.scenario,
            &mut rng,
        )?;
        let names: Vec<String> = placed
            .iter()
            .map(|p| lib[p.library_index].name.clone())
            .collect();
        // Without the sensor model, as the close-ups below (`look`).
        let mut cameras = cfg.cameras.clone();
        cameras.noise.enabled = false;
        let perception = Perception::new(cameras)?;
        let overview = perception.look(&world)?;
        let views = match scenario {
            Scenario::Isolated => 1,
            _ => setup.views_per_scene,
        }
        .min(overview.segments.len());
        let spec = cfg.grasp_spec();
        let top = f64::from(world.config().table.top_z_m());
        let gripper = &cfg.robot.gripper;
        let mut out = SceneOutput {
            views: Vec::new(),
            summary: GraspDataSummary::default(),
        };
        let start_s = world.time_s();
        for v in 0..views {
            let mut view_rng =
                ChaCha8Rng::seed_from_u64(derive_seed(setup.seed, TAG_VIEW, s as u64, v as u64));
            let Some(view) = self.look(&world, &overview, v, &mut view_rng)? else {
                continue;
            };
            let Some(target) = view.object else {
                continue;
            };
            let Some(aimed) = placed.iter().find(|p| p.handle == target) else {
                continue;
            };
            let mut proposals: Vec<(&'static str, usize, DecodedGrasp)> = Vec::new();
            let fallbacks = &cfg.attempt.fallback_openings_m;
            let mut analytic = AnalyticSource::new();
            let mut random =
                RandomSource::new(derive_seed(setup.seed, TAG_RANDOM, s as u64, v as u64));
            let mut rim = RimSource::default();
            for (name, source, k) in [
                (
                    "analytic",
                    &mut analytic as &mut dyn GraspSource,
                    setup.analytic,
                ),
                ("random", &mut random as &mut dyn GraspSource, setup.random),
                ("rim", &mut rim as &mut dyn GraspSource, setup.rim),
            ] {
                if k == 0 {
                    continue;
                }
                let grasps =
                    ranked_grasps(source, &view, &spec, k, fallbacks, &cfg.attempt.decode)?;
                proposals.extend(
                    grasps
                        .into_iter()
                        .take(k)
                        .enumerate()
                        .map(|(r, g)| (name, r, g)),
                );
            }
            let jaw_px =
                view.crop.size_px as f32 * cfg.cameras.crop.side_fraction(spec.finger_width_m);
            let mut image = ViewImage {
                rgb: view.crop.rgb.clone(),
                depth_m: view.crop.depth_m.clone(),
                size_px: view.crop.size_px as usize,
                info: GraspImageInfo {
                    number: 0,
                    prefix: String::new(),
                    instance: aimed.library_index as u32,
                    category: self
                        .categories
                        .binary_search(&lib[aimed.library_index].category)
                        .unwrap_or(0) as u32,
                    category_name: lib[aimed.library_index].category.clone(),
                    object: lib[aimed.library_index].name.clone(),
                    camera: view.shot.camera,
                    window: Some(view.crop.window),
                    positives: 0,
                    negatives: 0,
                    physics: Some(PhysicsLabels {
                        scene: s,
                        scenario: scenario.to_string(),
                        objects: names.clone(),
                        positives: Vec::new(),
                        negatives: Vec::new(),
                    }),
                },
                positives: Vec::new(),
                negatives: Vec::new(),
            };
            let physics = image.info.physics.as_mut().expect("just set");
            for (name, rank, g) in proposals {
                let Ok(wg) = view.grasp_in_world(&g, &cfg.attempt.decode) else {
                    continue;
                };
                let plan = plan_grasp_for(gripper, top, &view, &wg, &cfg.attempt);
                let trial = try_grasp(
                    &mut world,
                    gripper,
                    &FreeGrasp::from(&plan),
                    Some(target),
                    &cfg.attempt,
                )?;
                // Everything back where it rested for the next grasp.
                for p in &placed {
                    world.reset_object_pose(p.handle, &p.rest_pose)?;
                }
                world.settle();
                let reaches = plan.reaches_contacts(&cfg.attempt);
                let outcome = GraspOutcome {
                    source: name.into(),
                    rank,
                    success: trial.success,
                    reason: trial.reason.map(|r| r.as_str().to_string()),
                    reaches_contacts: reaches,
                };
                let rectangle = DecodedGrasp { jaw_px, ..g }.rectangle();
                let sm = &mut out.summary;
                sm.all.add(trial.success);
                sm.by_source
                    .entry(name.into())
                    .or_default()
                    .add(trial.success);
                sm.by_scenario
                    .entry(scenario.to_string())
                    .or_default()
                    .add(trial.success);
                if !reaches {
                    sm.refused_by_planner.add(trial.success);
                }
                if let Some(r) = trial.reason {
                    *sm.failures.entry(r.as_str().into()).or_default() += 1;
                }
                if trial.success {
                    image.positives.push(rectangle);
                    physics.positives.push(outcome);
                } else {
                    image.negatives.push(rectangle);
                    physics.negatives.push(outcome);
                }
            }
            if image.positives.is_empty() && image.negatives.is_empty() {
                continue;
            }
            image.info.positives = image.positives.len();
            image.info.negatives = image.negatives.len();
            out.views.push(image);
        }
        out.summary.sim_s = world.time_s() - start_s;
        Ok(out)
    }

    /// Overview segment `v` seen close up, varied by [`Randomise`]; `None` when the close-up
    /// shows nothing usable.
    fn look(
        &self,
        world: &World,
        overview: &crate::perception::SceneView,
        v: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Option<ObjectView>, SimError> {
        let r = &self.setup.randomise;
        let mut cameras = self.setup.config.cameras.clone();
        // The sets' own randomisation (`Randomise`) stands in for the sensor model
        // (`[cameras.noise]`), which grasp-data leaves off.
        cameras.noise.enabled = false;
        let base = Perception::new(cameras.clone())?;
        let Ok(point) = base.table_point_m(overview, v) else {
            return Ok(None);
        };
        cameras.closeup.height_above_table_m += rng.random_range(-1.0..=1.0) * r.camera_height_m;
        let perception = Perception::new(cameras)?;
        let mut shot = perception
            .config()
            .render_closeup(world, point)
            .map_err(PerceptionError::from)?;
        randomise_frame(&mut shot.frame, r, rng);
        match perception.view_from(shot, v, point) {
            Ok(view) => Ok(Some(view)),
            Err(PerceptionError::NothingInCloseup { .. } | PerceptionError::Crop(_)) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }
}

/// Scene `s`'s table and objects (library indices), and the random stream that then places
/// them: the first draws of the scene's own stream.
fn scene_table(
    setup: &GraspDataSetup,
    library: &[lgdm_pointcloud::objects::ObjectModel],
    s: usize,
) -> (Scenario, Vec<usize>, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(setup.seed, TAG_SCENE, s as u64, 0));
    let scenario = if rng.random::<f64>() < setup.isolated_share {
        Scenario::Isolated
    } else {
        [Scenario::Packed, Scenario::Pile, Scenario::Scattered][rng.random_range(0..3)]
    };
    let picks = round_objects(scenario, library, s, &setup.config.scenario, &mut rng);
    (scenario, picks, rng)
}

/// Scales each label's colour channels by its own factors and adds depth noise (see
/// [`Randomise`]); the draws depend on `rng` alone.
fn randomise_frame(frame: &mut RgbdFrame, r: &Randomise, rng: &mut ChaCha8Rng) {
    let mut gains = [[1.0f32; 3]; 256];
    if r.colour_gain > 0.0 {
        for g in gains.iter_mut() {
            for c in g.iter_mut() {
                *c = 1.0 + rng.random_range(-1.0..=1.0) * r.colour_gain;
            }
        }
    }
    for (px, &label) in frame.rgb.iter_mut().zip(&frame.label) {
        if label == LABEL_BACKGROUND {
            continue;
        }
        let g = gains[label as usize];
        for c in 0..3 {
            px[c] = (f32::from(px[c]) * g[c]).round().clamp(0.0, 255.0) as u8;
        }
    }
    let sigma = rng.random::<f32>() * r.depth_noise_m;
    if sigma > 0.0 {
        let noise = Normal::new(0.0f32, sigma).expect("a finite positive sigma");
        for d in frame.depth_m.iter_mut().filter(|d| **d > 0.0) {
            *d = (*d + noise.sample(rng)).max(1e-4);
        }
    }
}

impl GraspDataSummary {
    fn merge(&mut self, other: &GraspDataSummary) {
        let add = |a: &mut Tally, b: &Tally| {
            a.tried += b.tried;
            a.held += b.held;
        };
        add(&mut self.all, &other.all);
        add(&mut self.refused_by_planner, &other.refused_by_planner);
        for (k, t) in &other.by_source {
            add(self.by_source.entry(k.clone()).or_default(), t);
        }
        for (k, t) in &other.by_scenario {
            add(self.by_scenario.entry(k.clone()).or_default(), t);
        }
        for (k, n) in &other.failures {
            *self.failures.entry(k.clone()).or_default() += n;
        }
        self.sim_s += other.sim_s;
    }
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> SimError {
    SimError::RunDir {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

fn write_json(path: &Path, value: &impl Serialize) -> Result<(), SimError> {
    lgdm_base::fs::write_json(path, value).map_err(|e| io_error(path, e))
}

/// Writes view image `k` (`NN/pcdNNNN…`) and returns its index entry.
fn write_view(root: &Path, k: usize, view: ViewImage) -> Result<GraspImageInfo, SimError> {
    let number = cornell_number(k);
    let prefix = cornell_prefix(root, number);
    let dir = prefix.parent().expect("a prefix has a folder");
    std::fs::create_dir_all(dir).map_err(|e| io_error(dir, e))?;
    let with = |suffix: &str| PathBuf::from(format!("{}{suffix}", prefix.display()));
    let n = view.size_px;
    RgbImage::from_pixels(n, n, view.rgb)
        .write_png(&with("r.png"))
        .map_err(|e| io_error(&with("r.png"), e))?;
    write_depth_tiff(&with("d.tiff"), n, n, &view.depth_m)
        .map_err(|e| io_error(&with("d.tiff"), e))?;
    write_rectangles(&with("cpos.txt"), &view.positives)
        .map_err(|e| io_error(&with("cpos.txt"), e))?;
    write_rectangles(&with("cneg.txt"), &view.negatives)
        .map_err(|e| io_error(&with("cneg.txt"), e))?;
    Ok(GraspImageInfo {
        number,
        prefix: format!("{:02}/pcd{number:04}", number / 100),
        ..view.info
    })
}

/// Images in [`GRASP_PREVIEW`].
const PREVIEW_TILES: usize = 8;

/// A view's image with its rectangles drawn (positives green, negatives red) and a caption.
fn preview_tile(view: &ViewImage) -> RgbImage {
    let n = view.size_px;
    let mut img = RgbImage::from_pixels(n, n, view.rgb.clone());
    draw_rectangles(&mut img, &view.positives, &view.negatives);
    let physics = view.info.physics.as_ref();
    let caption = format!(
        "{} {} +{} -{}",
        view.info.object,
        physics.map_or("", |p| p.scenario.as_str()),
        view.positives.len(),
        view.negatives.len()
    );
    img.draw_text(4, 4, &caption, [255, 255, 255], 1);
    img
}

/// [`GRASP_PREVIEW`]: the set's first images in a grid of four columns.
fn write_preview(path: &Path, tiles: &[RgbImage]) -> Result<(), SimError> {
    let Some(first) = tiles.first() else {
        return Ok(());
    };
    let (w, h) = (first.width, first.height);
    let cols = tiles.len().min(4);
    let rows = tiles.len().div_ceil(cols);
    let mut sheet = RgbImage::new(cols * w, rows * h, [0, 0, 0]);
    for (i, tile) in tiles.iter().enumerate() {
        sheet.blit(tile, ((i % cols) * w) as i64, ((i / cols) * h) as i64);
    }
    sheet.write_png(path).map_err(|e| io_error(path, e))
}

/// What a grasp-data set holds (what `force` may remove): its files by their exact names,
/// the numbered folders of images `NN/pcdNNNN{r.png,d.tiff,cpos.txt,cneg.txt}`, and the
/// temporary files of those being written.
fn classify(name: &str, is_dir: bool) -> Entry {
    use lgdm_base::fs::temporary_target;
    let folder = |n: &str| n.len() == 2 && n.bytes().all(|b| b.is_ascii_digit());
    let image = |n: &str| {
        let Some(rest) = n.strip_prefix("pcd") else {
            return false;
        };
        ["r.png", "d.tiff", "cpos.txt", "cneg.txt"].iter().any(|s| {
            rest.strip_suffix(s)
                .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
        })
    };
    let own = |n: &str, ours: &dyn Fn(&str) -> bool| {
        if !is_dir && (ours(n) || temporary_target(n).is_some_and(ours)) {
            Entry::Ours
        } else {
            Entry::Foreign
        }
    };
    if let Some((outer, inner)) = name.split_once('/') {
        return if folder(outer) {
            own(inner, &image)
        } else {
            Entry::Foreign
        };
    }
    if folder(name) {
        return if is_dir {
            Entry::Folder
        } else {
            Entry::Foreign
        };
    }
    own(name, &|n| {
        n == INDEX_FILE || n == SETUP_FILE || n == GRASP_PREVIEW
    })
}

fn claim(out: &Path, force: bool) -> Result<DirLock, SimError> {
    let policy = Ownership {
        kind: "an lgdm grasp-data set",
        occupied: "holds another set; choose another directory or pass --force to replace it",
        classify: &classify,
    };
    lgdm_base::fs::claim(out, force, &policy).map_err(|e| SimError::RunDir {
        path: e.path,
        reason: e.reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policy_knows_a_set_by_its_file_names() {
        for (name, is_dir, want) in [
            ("index.json", false, Entry::Ours),
            ("grasp-data.json", false, Entry::Ours),
            (GRASP_PREVIEW, false, Entry::Ours),
            (".index.json.a1B2c3.tmp", false, Entry::Ours),
            ("00", true, Entry::Folder),
            ("00/pcd0001r.png", false, Entry::Ours),
            ("00/pcd0001d.tiff", false, Entry::Ours),
            ("00/pcd0001cneg.txt", false, Entry::Ours),
            ("00/.pcd0001cpos.txt.a1B2c3.tmp", false, Entry::Ours),
            ("holiday.png", false, Entry::Foreign),
            (".holiday.png.a1B2c3.tmp", false, Entry::Foreign),
            ("00/pcdholidayr.png", false, Entry::Foreign),
            ("00/holiday.png", false, Entry::Foreign),
            ("photos/pcd0001r.png", false, Entry::Foreign),
            ("00", false, Entry::Foreign),
        ] {
            assert_eq!(classify(name, is_dir), want, "{name} (dir: {is_dir})");
        }
    }
}
