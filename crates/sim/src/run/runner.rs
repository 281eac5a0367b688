//! Playing a run: rounds of a [`Scenario`] with one [`GraspSource`], every attempt recorded.
//!
//! [`run_trials`] plays `rounds` rounds (round r seeded with `derive_seed(seed, …, r)`, so the same
//! seed gives the same rounds): set the table ([`crate::tasks::scenario`]), look with the overview
//! camera, take a close-up crop per object ([`crate::perception`]), ask the source for ranked
//! grasps, and run attempts ([`crate::grasping::attempt`]) until the round ends, never trying
//! again a grasp that failed in the round ([`crate::grasping::failed`]). It returns
//! [`RunResults`] ([`crate::run::results`]).
//!
//! [`run_pick_place`] adds recognition in the loop ([`crate::recognition::recognizer`]): before
//! each attempt the object aimed at is recognised (once per object and round) and taught when the
//! robot did not know it or was wrong, with replay after each round. Two policies attach to it:
//! with [`RunSpec::packing`] each object goes to the basket of the category the robot recognises it
//! as and is judged against its true one ([`crate::tasks::packing`]; the basket is chosen once per
//! attempt), with [`RunSpec::arrival`] the categories arrive over time and the run ends with the
//! model's first guess about every object ([`crate::tasks::arrival`]). Everything else that watches
//! a run — recording, for one — is a [`RunObserver`] the runner calls at each event
//! ([`crate::run::observe`]); the results are the same with any observer.
//!
//! Progress is reported after every attempt and every round as a [`Progress`] of `attempts`
//! (when the run has an attempt budget) or of `rounds`.
//!
//! The whole job — objects, model, run directory — is one call of [`crate::run::job`]; these are
//! its parts.
//!
//! ```no_run
//! use lgdm_pointcloud::objects::{CATEGORIES, procedural_library};
//! use lgdm_sim::run::runner::run_trials;
//! use lgdm_sim::tasks::scenario::Scenario;
//! use lgdm_sim::grasping::source::AnalyticSource;
//! use lgdm_sim::run::spec::RunSpec;
//! let library = procedural_library(&CATEGORIES, 5, 0).unwrap();
//! let spec = RunSpec::new(Scenario::Isolated, 10, 0);
//! let results = run_trials(&spec, &library, &mut AnalyticSource::new(), &mut (), |_| {}).unwrap();
//! println!("grasp success {}", results.summary.grasp_success_rate.describe());
//! ```

use std::time::Instant;

use lgdm_base::Progress;
use lgdm_base::seed::derive_seed;
use lgdm_pointcloud::grasp::GraspSpec;
use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::objects::ObjectModel;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::grasping::attempt::{
    AttemptConfig, Cell, Execution, FailureReason, execute, park, plan_grasp,
};
use crate::grasping::failed::FailedGrasps;
use crate::grasping::proposals::checked_grasps;
use crate::grasping::source::GraspSource;
use crate::perception::{ObjectView, Perception, PerceptionError, SceneView, WorldGrasp};
use crate::physics::hull::SOLID_FRACTION;
use crate::physics::measure::{narrowest_width_m, solid_fraction};
use crate::physics::object::ObjectHandle;
use crate::physics::shapes::LibraryShapes;
use crate::physics::world::World;
use crate::recognition::recognizer::{MemoryPoint, RecognitionRecord, Recognizer};
use crate::run::error::SimError;
use crate::run::observe::{GraspShown, RecordCamera, RoundInfo, RunObserver};
use crate::run::results::{
    AttemptRecord, GraspRecord, PoseRecord, Proposals, RESULTS_FORMAT_VERSION, RecognitionRun,
    RoundEnd, RoundRecord, RunInfo, RunResults, RunWall, summarize,
};
use crate::run::spec::RunSpec;
use crate::run::state::{Checkpoint, RunState};
use crate::tasks::arrival::ArrivalRun;
use crate::tasks::packing::BasketChoice;
use crate::tasks::scenario::{PlacedObject, Scenario, on_table, round_objects_among, set_table};
use crate::timing::{WallTimes, Work};

/// Seed tag of a round's RNG.
const TAG_ROUND: u64 = 0x5133_0001;

/// Plays `spec.rounds` rounds of `spec.scenario` on `library` with `source`, telling `observer`
/// what happens and calling `on_progress` after every attempt and round. Checks the spec
/// ([`RunSpec::validate`]) before the first round.
pub fn run_trials(
    spec: &RunSpec,
    library: &[ObjectModel],
    source: &mut dyn GraspSource,
    observer: &mut dyn RunObserver,
    on_progress: impl FnMut(Progress),
) -> Result<RunResults, SimError> {
    let nothing = &mut |_: &RunState, _: Option<&Recognizer>| Ok(());
    play(
        spec,
        library,
        None,
        source,
        None,
        observer,
        on_progress,
        None,
        nothing,
    )
}

/// Pick-and-place with lifelong recognition: rounds as [`run_trials`] plays them, where before
/// each attempt the object aimed at is recognised by `recognizer` (see the module docs). The
/// recognizer keeps the model it learnt; the results hold every recognition, the first-guess
/// accuracy, the teacher interventions and the node counts after each round.
pub fn run_pick_place(
    spec: &RunSpec,
    library: &[ObjectModel],
    source: &mut dyn GraspSource,
    recognizer: &mut Recognizer,
    observer: &mut dyn RunObserver,
    on_progress: impl FnMut(Progress),
) -> Result<RunResults, SimError> {
    let recognizer = Some(recognizer);
    let nothing = &mut |_: &RunState, _: Option<&Recognizer>| Ok(());
    play(
        spec,
        library,
        None,
        source,
        recognizer,
        observer,
        on_progress,
        None,
        nothing,
    )
}

/// The colliders of every object the rounds of `spec` will show (as far as its attempt budget
/// lets them play): decomposed ahead, in parallel, and each built once in a scratch world, so a
/// mesh that cannot be simulated fails before the first round. Validates `spec` first.
pub fn prepare_shapes(
    spec: &RunSpec,
    library: &[ObjectModel],
    labels: Option<&crate::recognition::labels::Labels>,
) -> Result<LibraryShapes, SimError> {
    spec.validate(library, labels)?;
    let mut shapes = LibraryShapes::new(spec.config.shapes.clone(), library.len());
    // Every round has at least one attempt, so an attempt budget bounds the rounds played: the
    // work and memory set aside follow what the run can do, not `rounds` (the picks are the
    // rounds' first draws; the same seeds draw them again in each round).
    let used: Vec<usize> = (0..playable_rounds(spec))
        .flat_map(|round| round_picks(spec, library, round, &mut round_rng(spec, round)))
        .collect();
    shapes.prepare(library, &used);
    shapes.check(&spec.config.world, library, &used)?;
    Ok(shapes)
}

/// The rounds a run can play: `rounds`, or fewer when the attempt budget ends it first.
fn playable_rounds(spec: &RunSpec) -> usize {
    spec.max_attempts
        .map_or(spec.rounds, |a| a.min(spec.rounds))
}

/// A grasp candidate on one view.
struct Candidate {
    view: usize,
    rank: usize,
    crop: DecodedGrasp,
    world: WorldGrasp,
}

/// What the attempt in progress knows beyond its grasp: the recognition of the object aimed at
/// and, packing, the basket chosen from it.
struct Decision {
    recognition: Option<RecognitionRecord>,
    basket: Option<BasketChoice>,
}

impl Decision {
    /// An attempt that recognised nothing (nothing seen, no grasp): packing, the basket of
    /// nothing recognised.
    fn nothing(spec: &RunSpec) -> Self {
        Self {
            recognition: None,
            basket: spec.packing.as_ref().map(|p| p.choose(None)),
        }
    }
}

struct Runner<'a, F: FnMut(Progress)> {
    spec: &'a RunSpec,
    library: &'a [ObjectModel],
    source: &'a mut dyn GraspSource,
    perception: Perception,
    gripper: GraspSpec,
    shapes: LibraryShapes,
    attempts: Vec<AttemptRecord>,
    rounds_done: usize,
    on_progress: F,
    observer: &'a mut dyn RunObserver,
    /// Recognition in the loop (pick-and-place), when on.
    recognizer: Option<&'a mut Recognizer>,
    /// Node counts after each round (with a recognizer).
    memory: Vec<MemoryPoint>,
    /// Seconds of the rounds' end (replay).
    replay_s: f64,
    /// The round's recognitions so far, by object.
    recognised: Vec<(ObjectHandle, RecognitionRecord)>,
    /// The round's failed grasps ([`crate::grasping::failed`]).
    failed: FailedGrasps,
}

/// The timer and counters of one attempt in progress.
struct AttemptClock {
    start: Instant,
    sim_start_s: f64,
    wall: WallTimes,
    proposals: Proposals,
}

impl AttemptClock {
    fn start(world: &World) -> Self {
        Self {
            start: Instant::now(),
            sim_start_s: world.time_s(),
            wall: WallTimes::default(),
            proposals: Proposals::default(),
        }
    }
}

/// An attempt that tried no grasp.
fn no_grasp() -> Execution {
    Execution {
        reason: Some(FailureReason::NoGraspFound),
        ..Execution::default()
    }
}

impl<F: FnMut(Progress)> Runner<'_, F> {
    /// An attempt at `object` that tried no grasp: [`FailureReason::WiderThanGripper`] when the
    /// object is wider than the stroke whichever way the jaws turn ([`narrowest_width_m`]) and
    /// solid ([`solid_fraction`] at least [`SOLID_FRACTION`]), else no grasp found.
    fn no_grasp_at(&self, world: &World, object: Option<ObjectHandle>) -> Execution {
        let stroke = self.gripper.max_opening_m;
        let too_wide = object.is_some_and(|h| {
            narrowest_width_m(world, h).is_some_and(|w| w > stroke)
                && solid_fraction(world, h).is_some_and(|f| f >= SOLID_FRACTION)
        });
        match too_wide {
            true => Execution {
                reason: Some(FailureReason::WiderThanGripper),
                ..Execution::default()
            },
            _ => no_grasp(),
        }
    }

    fn progress(&mut self) {
        let p = match self.spec.max_attempts {
            Some(max) => Progress {
                stage: "attempts",
                done: self.attempts.len() as u64,
                total: max as u64,
            },
            None => Progress {
                stage: "rounds",
                done: self.rounds_done as u64,
                total: self.spec.rounds as u64,
            },
        };
        (self.on_progress)(p);
    }

    fn look(&mut self, cell: &Cell, clock: &mut AttemptClock) -> Result<SceneView, SimError> {
        let shot = clock.wall.time(Work::Render, || {
            self.perception.config().render_overview(&cell.world)
        });
        let shot = shot.map_err(PerceptionError::from)?;
        self.observer
            .camera_shot(&cell.world, RecordCamera::Overview, &shot);
        Ok(clock
            .wall
            .time(Work::Perception, || self.perception.segment_scene(shot))?)
    }

    /// The close-ups of segments `indices`, in that order; `None` for one that shows nothing
    /// usable. They are rendered and cropped on rayon's threads (each depends on the world
    /// alone), then recorded in order.
    fn close_ups(
        &mut self,
        cell: &Cell,
        scene: &SceneView,
        indices: std::ops::Range<usize>,
        clock: &mut AttemptClock,
    ) -> Result<Vec<Option<ObjectView>>, SimError> {
        let points: Vec<Option<[f32; 3]>> = indices
            .clone()
            .map(|index| self.perception.table_point_m(scene, index).ok())
            .collect();
        let perception = &self.perception;
        let shots = clock.wall.time(Work::Render, || {
            points
                .par_iter()
                .map(|point| {
                    point
                        .map(|point| perception.config().render_closeup(&cell.world, point))
                        .transpose()
                })
                .collect::<Result<Vec<_>, _>>()
        });
        let shots = shots.map_err(PerceptionError::from)?;
        for shot in shots.iter().flatten() {
            self.observer
                .camera_shot(&cell.world, RecordCamera::Closeup, shot);
        }
        let perception = &self.perception;
        let views = clock.wall.time(Work::Perception, || {
            shots
                .into_par_iter()
                .zip(points)
                .zip(indices)
                .map(|((shot, point), index)| {
                    let (Some(shot), Some(point)) = (shot, point) else {
                        return Ok(None);
                    };
                    match perception.view_from(shot, index, point) {
                        Ok(view) => Ok(Some(view)),
                        Err(
                            PerceptionError::NothingInCloseup { .. } | PerceptionError::Crop(_),
                        ) => Ok(None),
                        Err(e) => Err(e),
                    }
                })
                .collect::<Result<Vec<_>, _>>()
        });
        Ok(views?)
    }

    /// The source's ranked grasps on `view` that can be placed in the world (not yet checked
    /// against the plan: [`Runner::reaches`]).
    fn candidates(
        &mut self,
        view: &ObjectView,
        view_index: usize,
        clock: &mut AttemptClock,
    ) -> Result<Vec<Candidate>, SimError> {
        let k = self.spec.config.scenario.ranked_grasps;
        let source = &mut *self.source;
        let fallbacks = &self.spec.config.attempt.fallback_openings_m;
        let gripper = &self.gripper;
        let decode = &self.spec.config.attempt.decode;
        let check = self.spec.config.attempt.proposal_check.unwrap_or_default();
        let widen = self.spec.config.attempt.widen_when_refused;
        let checked = clock.wall.time(Work::Source, || {
            checked_grasps(source, view, gripper, k, fallbacks, decode, check, widen)
        })?;
        clock.proposals.checked += checked.checked;
        clock.proposals.check_refused += checked.refused;
        let grasps = checked.grasps;
        Ok(clock.wall.time(Work::Perception, || {
            grasps
                .iter()
                .take(k)
                .enumerate()
                .filter_map(|(rank, g)| {
                    view.grasp_in_world(g, decode).ok().map(|world| Candidate {
                        view: view_index,
                        rank,
                        crop: *g,
                        world,
                    })
                })
                .collect()
        }))
    }

    /// Whether `candidate`'s pads, as planned in `cell`, close on something
    /// ([`crate::grasping::attempt::GraspPlan::reaches_contacts`]): a plan that would close on air
    /// is never tried.
    fn reaches(
        &self,
        cell: &Cell,
        view: &ObjectView,
        candidate: &Candidate,
        clock: &mut AttemptClock,
    ) -> bool {
        let attempt = &self.spec.config.attempt;
        let reaches = clock.wall.time(Work::Planning, || {
            plan_grasp(cell, view, &candidate.world, attempt).reaches_contacts(attempt)
        });
        clock.proposals.planned += 1;
        clock.proposals.refused += usize::from(!reaches);
        reaches
    }

    /// Adds the record of an attempt at `target` (the object aimed at) that tried `grasp`.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        cell: &Cell,
        (round, try_in_round): (usize, usize),
        objects: &[PlacedObject],
        target: Option<ObjectHandle>,
        grasp: Option<GraspRecord>,
        exec: Execution,
        target_pose: Option<Pose>,
        decision: Decision,
        mut clock: AttemptClock,
    ) {
        let find = |h: ObjectHandle| objects.iter().find(|o| o.handle == h);
        let aimed = target.and_then(find);
        let grasped = exec
            .pinched_object
            .filter(|h| Some(*h) != target)
            .and_then(find)
            .map(|o| o.name.clone());
        // Packing: the basket the attempt carried to, judged against the true category of the
        // object carried. Attempts at no object (nothing seen, no grasp anywhere) carry no
        // packing record.
        let (packing, reason) = match (&self.spec.packing, decision.basket) {
            (Some(spec), Some(choice)) if target.is_some() || grasp.is_some() => {
                let carried = exec.pinched_object.or(target).and_then(find);
                let (record, reason) = crate::tasks::packing::judge(
                    spec,
                    choice,
                    carried.map(|o| o.category.as_str()),
                    exec.placement_success,
                    exec.reason,
                );
                (Some(record), reason)
            }
            _ => (None, exec.reason),
        };
        clock.wall.finish(clock.start);
        self.attempts.push(AttemptRecord {
            index: self.attempts.len(),
            round,
            try_in_round,
            object: aimed.map(|o| o.name.clone()),
            category: aimed.map(|o| o.category.clone()),
            object_pose: target_pose.as_ref().map(PoseRecord::from),
            grasped_object: grasped,
            grasp,
            grasp_success: exec.grasp_success,
            contact_only_success: exec.contact_only_success,
            placement_success: exec.placement_success,
            reason,
            recognition: decision.recognition,
            packing,
            measured: exec.measured,
            proposals: clock.proposals,
            sim_time_s: cell.world.time_s() - clock.sim_start_s,
            wall: clock.wall,
        });
        if let Some(a) = self.attempts.last() {
            self.observer.attempt_recorded(a);
        }
        self.progress();
    }

    /// What the robot makes of `target` before it grasps it: recognition in the loop (the first
    /// guess, once per object and round — later attempts at it repeat that record — and the
    /// teacher's lesson when needed) and, packing, the basket chosen from it. Nothing to
    /// recognise without a recognizer or a known target.
    fn decide(
        &mut self,
        cell: &Cell,
        target: Option<ObjectHandle>,
        objects: &[PlacedObject],
        clock: &mut AttemptClock,
    ) -> Result<Decision, SimError> {
        let recognition = self.recognise(cell, target, objects, clock)?;
        let basket = self
            .spec
            .packing
            .as_ref()
            .map(|p| p.choose(recognition.as_ref()));
        Ok(Decision {
            recognition,
            basket,
        })
    }

    fn recognise(
        &mut self,
        cell: &Cell,
        target: Option<ObjectHandle>,
        objects: &[PlacedObject],
        clock: &mut AttemptClock,
    ) -> Result<Option<RecognitionRecord>, SimError> {
        let (Some(recognizer), Some(h)) = (self.recognizer.as_deref_mut(), target) else {
            return Ok(None);
        };
        let Some(object) = objects.iter().find(|o| o.handle == h) else {
            return Ok(None);
        };
        if let Some((_, earlier)) = self.recognised.iter().find(|(k, _)| *k == h) {
            return Ok(Some(RecognitionRecord {
                first_look: false,
                ..earlier.clone()
            }));
        }
        let instance = &self.library[object.library_index].name;
        let record =
            recognizer.encounter(&cell.world, h, &object.category, instance, &mut clock.wall)?;
        self.observer.recognised(&cell.world, h, &record);
        self.recognised.push((h, record.clone()));
        Ok(Some(record))
    }

    /// Whether the run's attempt budget is spent.
    fn budget_spent(&self) -> bool {
        self.spec
            .max_attempts
            .is_some_and(|max| self.attempts.len() >= max)
    }

    /// Tries `candidate` from `views`, carrying to the basket `decision` chose (else the
    /// config's); parks the arm after.
    fn attempt(
        &mut self,
        cell: &mut Cell,
        views: &[ObjectView],
        candidate: &Candidate,
        decision: &Decision,
        clock: &mut AttemptClock,
    ) -> Result<(Option<ObjectHandle>, GraspRecord, Execution), SimError> {
        let view = &views[candidate.view];
        let spec = self.spec;
        let packing_cfg;
        let cfg = match &decision.basket {
            Some(c) if c.basket != spec.config.attempt.target_basket => {
                packing_cfg = AttemptConfig {
                    target_basket: c.basket,
                    ..spec.config.attempt.clone()
                };
                &packing_cfg
            }
            _ => &spec.config.attempt,
        };
        if let Some(c) = &decision.basket {
            self.observer.basket_chosen(&cell.world, c);
        }
        let plan = clock.wall.time(Work::Planning, || {
            plan_grasp(cell, view, &candidate.world, cfg)
        });
        let object = view
            .object
            .and_then(|h| cell.world.object_name(h).ok())
            .map(str::to_string);
        let gripper = cell.robot.gripper().config().clone();
        let shown = GraspShown {
            plan: &plan,
            rank: candidate.rank,
            object: object.as_deref(),
            gripper: &gripper,
            crop: Some((&view.crop, candidate.crop.rectangle())),
        };
        self.observer.grasp_planned(&cell.world, &shown);
        let mut exec = execute(cell, &plan, view.object, cfg, &mut clock.wall)?;
        // A held object was carried to the basket: the carry height is clear there. Otherwise
        // the fingers are among the objects: back up to the pre-grasp height first.
        let up_to_z_m = if exec.grasp_success {
            plan.pregrasp_z_m.min(cfg.carry_height_m)
        } else {
            plan.pregrasp_z_m
        };
        park(cell, up_to_z_m, cfg, &mut clock.wall)?;
        // The way back is part of the attempt: what its links touched joins the record.
        for contact in std::mem::take(&mut cell.arm_contacts) {
            if !exec.measured.arm_contacts.contains(&contact) {
                exec.measured.arm_contacts.push(contact);
            }
        }
        self.observer
            .grasp_done(cell, &shown, &exec, cfg.target_basket)
            .map_err(SimError::Observer)?;
        let record = GraspRecord {
            rank: candidate.rank,
            crop: candidate.crop,
            plan,
        };
        Ok((view.object, record, exec))
    }

    fn round(&mut self, round: usize) -> Result<(RoundRecord, f64), SimError> {
        let round_start = Instant::now();
        let cfg = &self.spec.config;
        let scenario = self.spec.scenario;
        let mut rng = round_rng(self.spec, round);
        let picks = round_picks(self.spec, self.library, round, &mut rng);
        let setup_start = Instant::now();
        let mut world = World::new(cfg.world.clone())?;
        let info = RoundInfo {
            round,
            scenario,
            grasp_source: self.source.name(),
            seed: self.spec.seed,
            objects: &self.spec.objects,
        };
        self.observer
            .round_started(&mut world, &info)
            .map_err(SimError::Observer)?;
        let objects = set_table(
            &mut world,
            scenario,
            self.library,
            &mut self.shapes,
            &picks,
            &cfg.scenario,
            &mut rng,
        )?;
        let mut cell = Cell::at_ready(world, cfg.robot.clone(), &cfg.attempt)?;
        self.observer.table_set(&cell, &objects);
        let setup_s = setup_start.elapsed().as_secs_f64();
        let sim_start = cell.world.time_s();
        let first_attempt = self.attempts.len();
        self.recognised.clear();
        self.failed.clear();
        let mut placed = 0usize;
        let mut left_table = Vec::new();
        let ended_by = match scenario {
            Scenario::Isolated => self.isolated(&mut cell, round, &objects, &mut placed)?,
            Scenario::Packed | Scenario::Pile | Scenario::Scattered => {
                self.clutter(&mut cell, round, &objects, &mut placed, &mut left_table)?
            }
        };
        let mut wall = WallTimes::default();
        for a in &self.attempts[first_attempt..] {
            wall.add(&a.wall);
        }
        if let Some(recognizer) = self.recognizer.as_deref_mut() {
            let start = Instant::now();
            let point = recognizer.end_round(&mut wall)?;
            self.replay_s += start.elapsed().as_secs_f64();
            self.memory.push(point);
        }
        wall.finish(round_start);
        let record = RoundRecord {
            round,
            objects: objects.iter().map(|o| o.name.clone()).collect(),
            attempts: self.attempts.len() - first_attempt,
            placed,
            left_table,
            ended_by,
            sim_time_s: cell.world.time_s() - sim_start,
            wall,
        };
        self.observer
            .round_ended(&mut cell.world, &record)
            .map_err(SimError::Observer)?;
        Ok((record, setup_s))
    }

    /// A round of the isolated table: one object, its ranked grasps tried in turn (skipping
    /// those at the place and angle of one that failed), the object put back where it rested
    /// after each failed try.
    fn isolated(
        &mut self,
        cell: &mut Cell,
        round: usize,
        objects: &[PlacedObject],
        placed: &mut usize,
    ) -> Result<RoundEnd, SimError> {
        let object = &objects[0];
        let mut clock = AttemptClock::start(&cell.world);
        let scene = self.look(cell, &mut clock)?;
        let view = match scene.segments.is_empty() {
            true => None,
            // The largest segment: the object (the isolated table holds one).
            false => self
                .close_ups(cell, &scene, 0..1, &mut clock)?
                .pop()
                .flatten(),
        };
        let pose = cell.world.object_pose(object.handle).ok();
        let Some(view) = view else {
            let at = Some(object.handle);
            self.record(
                cell,
                (round, 0),
                objects,
                at,
                None,
                no_grasp(),
                pose,
                Decision::nothing(self.spec),
                clock,
            );
            return Ok(RoundEnd::NothingSeen);
        };
        let candidates: Vec<Candidate> = self
            .candidates(&view, 0, &mut clock)?
            .into_iter()
            .filter(|c| self.reaches(cell, &view, c, &mut clock))
            .collect();
        let aimed = view.object.or(Some(object.handle));
        if candidates.is_empty() {
            let exec = self.no_grasp_at(&cell.world, aimed);
            self.record(
                cell,
                (round, 0),
                objects,
                aimed,
                None,
                exec,
                pose,
                Decision::nothing(self.spec),
                clock,
            );
            return Ok(RoundEnd::GraspsExhausted);
        }
        let views = [view];
        let mut first = Some(clock);
        let mut tries = 0usize;
        let mut next = Some(0);
        while let Some(i) = next {
            let candidate = &candidates[i];
            if self.budget_spent() {
                return Ok(RoundEnd::AttemptBudget);
            }
            let mut clock = first
                .take()
                .unwrap_or_else(|| AttemptClock::start(&cell.world));
            let pose = cell.world.object_pose(object.handle).ok();
            let decision = self.decide(cell, aimed, objects, &mut clock)?;
            let (target, grasp, exec) =
                self.attempt(cell, &views, candidate, &decision, &mut clock)?;
            let done = exec.placement_success;
            if done {
                *placed += 1;
                cell.world.remove_object(object.handle)?;
                next = None;
            } else {
                // Put the object back where it rested.
                clock.wall.time(Work::Physics, || {
                    cell.world
                        .reset_object_pose(object.handle, &object.rest_pose)
                        .map(|()| cell.world.settle())
                })?;
                // The next ranked grasp that did not fail already (the object rests where it
                // did, so the world frame is the object's); those skipped count here.
                let g = &candidate.world;
                self.failed.remember(g.position_m, g.yaw_rad);
                next = (i + 1..candidates.len()).find(|&j| {
                    let g = &candidates[j].world;
                    let repeat = self.failed.covers(g.position_m, g.yaw_rad);
                    clock.proposals.repeat_skipped += usize::from(repeat);
                    !repeat
                });
            }
            let at = target.or(Some(object.handle));
            self.record(
                cell,
                (round, tries),
                objects,
                at,
                Some(grasp),
                exec,
                pose,
                decision,
                clock,
            );
            tries += 1;
            if done {
                return Ok(RoundEnd::Cleared);
            }
        }
        Ok(RoundEnd::GraspsExhausted)
    }

    /// A round of a cluttered table: until it is clear, the best grasp over every object's
    /// close-up that did not fail earlier in the round (with the memory of failed grasps off:
    /// after `k` failures in a row the `k`-th best), until too many failures in a row, a look
    /// with no grasp left, the per-round cap or the run's budget.
    fn clutter(
        &mut self,
        cell: &mut Cell,
        round: usize,
        objects: &[PlacedObject],
        placed: &mut usize,
        left_table: &mut Vec<String>,
    ) -> Result<RoundEnd, SimError> {
        let cfg = self.spec.config.scenario.clone();
        let mut consecutive = 0usize;
        let mut tries = 0usize;
        loop {
            // Objects that left the table (knocked off, dropped in a basket) leave the round.
            let live: Vec<ObjectHandle> = cell.world.objects().collect();
            for h in live {
                if !on_table(&cell.world, h)? {
                    if let Some(o) = objects.iter().find(|o| o.handle == h) {
                        left_table.push(o.name.clone());
                    }
                    cell.world.remove_object(h)?;
                }
            }
            if cell.world.objects().next().is_none() {
                return Ok(RoundEnd::Cleared);
            }
            if consecutive >= cfg.max_consecutive_failures {
                return Ok(RoundEnd::ConsecutiveFailures);
            }
            if tries >= cfg.max_attempts_per_round {
                return Ok(RoundEnd::AttemptCap);
            }
            if self.budget_spent() {
                return Ok(RoundEnd::AttemptBudget);
            }
            let mut clock = AttemptClock::start(&cell.world);
            let (views, candidates) = self.survey(cell, &mut clock)?;
            tries += 1;
            let at = (round, tries - 1);
            // With the memory of failed grasps on, the best candidate that did not fail this
            // round and whose pads close on something; with it off, the `consecutive`-th of
            // those (after as many failures in a row), else the last of them. Planned best
            // first, only as far as needed.
            let skip = match self.failed.is_on() {
                true => 0,
                false => consecutive,
            };
            let mut chosen = None;
            let mut reaching = 0;
            for c in &candidates {
                if self.failed.covers(c.world.position_m, c.world.yaw_rad) {
                    clock.proposals.repeat_skipped += 1;
                    continue;
                }
                if self.reaches(cell, &views[c.view], c, &mut clock) {
                    chosen = Some(c);
                    if reaching == skip {
                        break;
                    }
                    reaching += 1;
                }
            }
            let Some(candidate) = chosen else {
                // Attributed to the largest segment's object, which the attempt would have
                // aimed at first.
                let aimed = views.first().and_then(|v| v.object);
                let exec = self.no_grasp_at(&cell.world, aimed);
                self.record(
                    cell,
                    at,
                    objects,
                    aimed,
                    None,
                    exec,
                    None,
                    Decision::nothing(self.spec),
                    clock,
                );
                if cfg.end_round_without_grasp {
                    return Ok(RoundEnd::NoGrasp);
                }
                consecutive += 1;
                continue;
            };
            let target = views[candidate.view].object;
            let pose = target.and_then(|h| cell.world.object_pose(h).ok());
            let decision = self.decide(cell, target, objects, &mut clock)?;
            let (target, grasp, exec) =
                self.attempt(cell, &views, candidate, &decision, &mut clock)?;
            if exec.placement_success {
                *placed += 1;
                consecutive = 0;
                if let Some(h) = exec.pinched_object {
                    cell.world.remove_object(h)?;
                }
            } else {
                consecutive += 1;
                let g = &candidate.world;
                self.failed.remember(g.position_m, g.yaw_rad);
            }
            clock.wall.time(Work::Physics, || cell.world.settle());
            self.record(
                cell,
                at,
                objects,
                target,
                Some(grasp),
                exec,
                pose,
                decision,
                clock,
            );
        }
    }

    /// One look at a cluttered table: a close-up of every segment and the source's grasps on
    /// each, best first (ties by view, then rank).
    fn survey(
        &mut self,
        cell: &Cell,
        clock: &mut AttemptClock,
    ) -> Result<(Vec<ObjectView>, Vec<Candidate>), SimError> {
        let scene = self.look(cell, clock)?;
        let mut views = Vec::new();
        let mut candidates = Vec::new();
        for view in self
            .close_ups(cell, &scene, 0..scene.segments.len(), clock)?
            .into_iter()
            .flatten()
        {
            candidates.extend(self.candidates(&view, views.len(), clock)?);
            views.push(view);
        }
        candidates.sort_by(|a, b| {
            b.world
                .quality
                .total_cmp(&a.world.quality)
                .then(a.view.cmp(&b.view))
                .then(a.rank.cmp(&b.rank))
        });
        Ok((views, candidates))
    }
}

/// Plays the run; `shapes` from [`prepare_shapes`] (prepared here when `None`); from `resume`
/// on (the state after its finished rounds; `source` and `recognizer` built as for the run it
/// continues, the recognizer already restored), calling `checkpoint` after every round.
#[allow(clippy::too_many_arguments)]
pub(crate) fn play(
    spec: &RunSpec,
    library: &[ObjectModel],
    shapes: Option<LibraryShapes>,
    source: &mut dyn GraspSource,
    recognizer: Option<&mut Recognizer>,
    observer: &mut dyn RunObserver,
    on_progress: impl FnMut(Progress),
    resume: Option<RunState>,
    checkpoint: Checkpoint<'_>,
) -> Result<RunResults, SimError> {
    let start = Instant::now();
    // An unset proposal check is the source's own (recorded in the results as resolved).
    let resolved;
    let spec = match spec.config.attempt.proposal_check {
        Some(_) => spec,
        None => {
            let mut s = spec.clone();
            s.config.attempt.proposal_check = Some(source.proposal_check());
            resolved = s;
            &resolved
        }
    };
    let labels = recognizer.as_deref().map(Recognizer::labels);
    // Shapes given come from `prepare_shapes` on this spec (a job's), which validated it.
    let shapes = match shapes {
        Some(shapes) => shapes,
        None => prepare_shapes(spec, library, labels)?,
    };
    let perception = Perception::new(spec.config.cameras.clone())?;
    let mut arrival = spec.arrival.as_ref().map(|a| {
        let at = spec.config.scenario.clutter_center_xy_m;
        ArrivalRun::new(a, &spec.config.world, library, at, spec.seed)
    });
    let mut runner = Runner {
        spec,
        library,
        gripper: spec.config.grasp_spec(),
        shapes,
        source,
        perception,
        attempts: Vec::new(),
        rounds_done: 0,
        on_progress,
        observer,
        memory: recognizer.iter().map(|r| r.memory_point()).collect(),
        recognizer,
        replay_s: 0.0,
        recognised: Vec::new(),
        failed: FailedGrasps::new(
            spec.config.scenario.failed_grasp_radius_m,
            spec.config.scenario.failed_grasp_angle_deg,
        ),
    };
    let mut rounds = Vec::with_capacity(playable_rounds(spec));
    let (mut setup_s, mut sim_s, mut evaluation_before) = (0.0, 0.0, 0.0);
    if let Some(state) = resume {
        if let Some(s) = &state.source {
            runner.source.restore(s)?;
        }
        if let Some(a) = &mut arrival {
            a.restore(state.at_switch.clone());
        }
        runner.attempts = state.attempts;
        runner.memory = state.memory;
        runner.rounds_done = state.rounds_done;
        runner.replay_s = state.wall.replay_s;
        rounds = state.rounds;
        setup_s = state.wall.setup_s;
        sim_s = state.sim_s;
        evaluation_before = state.wall.evaluation_s;
    }
    for r in runner.rounds_done..spec.rounds {
        if runner.budget_spent() {
            break;
        }
        if let (Some(a), Some(recognizer)) = (&mut arrival, runner.recognizer.as_deref_mut()) {
            a.before_round(r, recognizer)?;
        }
        let (record, setup) = runner.round(r)?;
        setup_s += setup;
        sim_s += record.sim_time_s;
        rounds.push(record);
        runner.rounds_done = r + 1;
        let state = RunState {
            rounds_done: runner.rounds_done,
            attempts: runner.attempts.clone(),
            rounds: rounds.clone(),
            memory: runner.memory.clone(),
            recognizer: runner.recognizer.as_deref().map(Recognizer::state),
            source: runner.source.state(),
            at_switch: arrival.as_ref().and_then(|a| a.at_switch().cloned()),
            sim_s,
            wall: RunWall {
                setup_s,
                replay_s: runner.replay_s,
                evaluation_s: evaluation_before + arrival.as_ref().map_or(0.0, |a| a.evaluation_s),
                ..RunWall::default()
            },
        };
        checkpoint(&state, runner.recognizer.as_deref())?;
        runner.progress();
    }
    let (arrival_evaluation, evaluation_s) = match (arrival, runner.recognizer.as_deref_mut()) {
        (Some(a), Some(r)) => {
            let (e, s) = a.finish(r, rounds.len())?;
            (Some(e), evaluation_before + s)
        }
        _ => (None, 0.0),
    };
    let recognition = runner.recognizer.as_deref().map(|r| RecognitionRun {
        encoder: r.encoder_name().to_string(),
        start_model: r.origin().to_string(),
        config: r.config().clone(),
        labels: r.labels().clone(),
        memory: runner.memory.clone(),
    });
    let attempts = runner.attempts;
    let mut summary = summarize(
        &attempts,
        &rounds,
        spec.packing.is_some(),
        &spec.config.scenario,
        spec.seed,
    );
    if let Some(e) = &arrival_evaluation {
        summary.early_category_accuracy_at_end = Some(e.at_end.early_category_accuracy);
        summary.early_instance_accuracy_at_end = Some(e.at_end.early_instance_accuracy);
        summary.early_category_accuracy_at_switch =
            e.at_switch.as_ref().map(|s| s.early_category_accuracy);
    }
    let mut attempt_wall = WallTimes::default();
    for a in &attempts {
        attempt_wall.add(&a.wall);
    }
    let total_s = start.elapsed().as_secs_f64();
    Ok(RunResults {
        format_version: RESULTS_FORMAT_VERSION,
        run: RunInfo {
            scenario: spec.scenario,
            grasp_source: runner.source.name().to_string(),
            grasp_source_detail: runner.source.describe(),
            rounds: rounds.len(),
            seed: spec.seed,
            objects: spec.objects.clone(),
            library_size: library.len(),
            packing: spec.packing.clone(),
            arrival: spec.arrival.clone(),
        },
        summary,
        wall: RunWall {
            total_s,
            setup_s,
            attempts: attempt_wall,
            per_attempt_s: attempt_wall.total_s / attempts.len().max(1) as f64,
            real_time_factor: if total_s > 0.0 { sim_s / total_s } else { 0.0 },
            replay_s: runner.replay_s,
            evaluation_s,
        },
        attempts,
        rounds,
        config: spec.config.clone(),
        recognition,
        arrival_evaluation,
    })
}

/// The library indices of round `round`'s objects: drawn from the whole library, or from the
/// categories of the round's stage when they arrive over time.
fn round_picks(
    spec: &RunSpec,
    library: &[ObjectModel],
    round: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let pool: Vec<usize> = match &spec.arrival {
        Some(a) => a.pool(library, round),
        None => (0..library.len()).collect(),
    };
    round_objects_among(
        spec.scenario,
        library,
        &pool,
        round,
        &spec.config.scenario,
        rng,
    )
}

/// The random stream of round `round`: it draws the round's objects, then their poses.
fn round_rng(spec: &RunSpec, round: usize) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(derive_seed(
        spec.seed,
        TAG_ROUND,
        round as u64,
        spec.scenario as u64,
    ))
}
