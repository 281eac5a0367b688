//! The scenarios of the reference protocol (`SIM-NOTES.md` §1.4): how the table is set for a
//! round, and how many grasps a round may try.
//!
//! - [`Scenario::Isolated`]: one object dropped upright with a uniform yaw at a uniform position
//!   in the reference region ((0.05, −0.52) ± 0.10 m); up to
//!   [`ScenarioConfig::ranked_grasps`] ranked grasps on one prediction, the object reset to its
//!   resting pose after each failed try. Round r shows object r of the library taken
//!   category by category in turn (mug, teapot, …, then the second instance of each, …).
//! - [`Scenario::Packed`]: [`ScenarioConfig::clutter_objects`] objects (a seeded draw from the
//!   library): one upright at the centre, then one from each side (+x, −x, +y, −y) slid toward
//!   the centre in [`ScenarioConfig::packed_step_m`] steps from
//!   [`ScenarioConfig::packed_start_m`] until its hull touches one already placed, then backed
//!   off one step (the reference's `create_packed`); all with uniform yaws, then settled.
//! - [`Scenario::Scattered`]: the same number of objects placed upright at uniform yaws and
//!   uniform positions within ± [`ScenarioConfig::scattered_half_extent_m`] of the centre, each
//!   at least [`ScenarioConfig::scattered_clearance_m`] from the others (a finger's room; up to
//!   [`ScenarioConfig::scattered_tries`] draws, then the one farthest from the others), then
//!   settled: the paper's pick-and-place and packing tables ("randomly placed").
//! - [`Scenario::Pile`]: the same number of objects dropped one after another with uniform
//!   orientations within ± [`ScenarioConfig::pile_spread_m`] of the centre, each released
//!   [`ScenarioConfig::pile_drop_gap_m`] above the pile so far and settled, inside a temporary
//!   box of four walls ([`ScenarioConfig::pile_box_m`]), swapped for a wider one once the pile
//!   rests, which is removed once it rests again (the reference's `create_pile`).
//!
//! In packed and pile rounds every attempt starts from a fresh overview image; the grasp tried
//! is the best over all objects that did not fail earlier in the round (within
//! [`ScenarioConfig::failed_grasp_radius_m`] and [`ScenarioConfig::failed_grasp_angle_deg`];
//! with that memory off, the best after no failure, the second best after one, …). A round
//! ends when the table is clear, after [`ScenarioConfig::max_consecutive_failures`] failures in
//! a row, when a look finds no grasp left, or after
//! [`ScenarioConfig::max_attempts_per_round`] attempts. Placed objects are
//! removed, and so are objects that left the table.
//!
//! ```
//! use lgdm_pointcloud::objects::procedural_library;
//! use lgdm_sim::tasks::scenario::{Scenario, ScenarioConfig, set_table};
//! use lgdm_sim::physics::shapes::LibraryShapes;
//! use lgdm_sim::physics::config::WorldConfig;
//! use lgdm_sim::physics::world::World;
//! use rand::SeedableRng;
//! let library = procedural_library(&["can", "book", "mug", "apple", "glass"], 1, 0).unwrap();
//! let mut world = World::new(WorldConfig::default()).unwrap();
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
//! let picks: Vec<usize> = (0..5).collect();
//! let mut shapes = LibraryShapes::hulls(library.len());
//! let placed = set_table(&mut world, Scenario::Packed, &library, &mut shapes, &picks, &ScenarioConfig::default(), &mut rng).unwrap();
//! assert_eq!(placed.len(), 5);
//! assert_eq!("pile".parse::<Scenario>().unwrap(), Scenario::Pile);
//! ```

use lgdm_pointcloud::math::Pose;
use lgdm_pointcloud::objects::ObjectModel;
use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, RngExt};
use rapier3d::parry::query::{distance, intersection_test};
use rapier3d::prelude::ColliderHandle;
use serde::{Deserialize, Serialize};

use crate::physics::drop_region::{DropRegion, uniform_rotation};
use crate::physics::error::WorldError;
use crate::physics::object::ObjectHandle;
use crate::physics::rapier::pose_to_rapier;
use crate::physics::shapes::LibraryShapes;
use crate::physics::world::{Scenery, World};

/// How the table is set for a round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scenario {
    /// One object at a time.
    Isolated,
    /// Objects pushed together.
    Packed,
    /// Objects dropped in a heap.
    Pile,
    /// Objects placed apart at random.
    Scattered,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 4] = [Self::Isolated, Self::Packed, Self::Pile, Self::Scattered];

    /// The name as the cli spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Isolated => "isolated",
            Self::Packed => "packed",
            Self::Pile => "pile",
            Self::Scattered => "scattered",
        }
    }
}

impl std::fmt::Display for Scenario {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// An unknown scenario name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown scenario `{0}` (known: isolated, packed, pile, scattered)")]
pub struct UnknownScenario(pub String);

impl std::str::FromStr for Scenario {
    type Err = UnknownScenario;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|c| c.as_str() == s)
            .ok_or_else(|| UnknownScenario(s.to_string()))
    }
}

/// Scenario constants. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScenarioConfig {
    /// Where isolated objects are dropped (default: (0.05, −0.52) ± 0.10 m, upright, uniform
    /// yaw, 1 cm above the table; the reference `isolated_obj_scenario`).
    pub isolated_region: DropRegion,
    /// Ranked grasps tried per prediction in the isolated scenario (default 3).
    pub ranked_grasps: usize,
    /// A packed or pile round ends after this many failed attempts in a row (default 3).
    pub max_consecutive_failures: usize,
    /// A cluttered round also ends when a look finds no grasp on anything left (default true):
    /// nothing moved, so another look would find none either, and the reference's loop recorded
    /// the same failure again up to `max_consecutive_failures` times (in 50 pile rounds 57 of
    /// 86 no-grasp attempts were such repeats). VGN's clutter-removal protocol ends a round the
    /// same way. The attempt that found nothing is still recorded, as one failure.
    pub end_round_without_grasp: bool,
    /// A grasp tried this round whose centre lies within this distance of a grasp that failed
    /// earlier in the round (m, world), its jaw axis within `failed_grasp_angle_deg`, is not
    /// tried again: it is skipped as a lower-ranked candidate would be, in every scenario and
    /// for every grasp source ([`crate::grasping::failed`]); 0 switches the memory off, and
    /// cluttered rounds then take the `k`-th best grasp after `k` failures in a row, as the
    /// reference does (default 0.02).
    pub failed_grasp_radius_m: f64,
    /// The angle between jaw axes within which a grasp counts as a failed one, modulo 180°
    /// (degrees, at most 90; default 15).
    pub failed_grasp_angle_deg: f64,
    /// Objects in a packed or pile round (default 5).
    pub clutter_objects: usize,
    /// Centre of the packed and pile arrangements on the table (m; default (0.05, −0.52)).
    pub clutter_center_xy_m: [f32; 2],
    /// Distance from the centre at which packed side objects start sliding (m; default 0.30,
    /// the reference margin).
    pub packed_start_m: f32,
    /// Slide step of packed side objects (m; default 0.01, the reference's).
    pub packed_step_m: f32,
    /// Half extent of the pile's drop square (m; default 0.025, the reference's).
    pub pile_spread_m: f32,
    /// Inner sides of the temporary boxes: the pile is dropped into the first; once it rests
    /// the box is swapped for the second, which is removed once the pile rests again (m;
    /// default [0.30, 0.45], the reference's).
    pub pile_box_m: [f32; 2],
    /// Height of that box's walls (m; default 0.15).
    pub pile_box_height_m: f32,
    /// Each pile object is released with its lowest point this far above the pile's top (m;
    /// default 0.02).
    pub pile_drop_gap_m: f32,
    /// Most attempts in one round (default 20).
    pub max_attempts_per_round: usize,
    /// Half extent of the square scattered objects are placed in (m; default 0.18: the arm
    /// reaches (0.05, −0.52) ± 0.20 m top-down, and the overview camera sees ± 0.40 m).
    pub scattered_half_extent_m: f32,
    /// Least distance between scattered objects' colliders (m; default 0.04: a finger and its
    /// clearance fit between them, and segmentation keeps them apart).
    pub scattered_clearance_m: f32,
    /// Position draws per scattered object before taking the one farthest from the others
    /// (default 50).
    pub scattered_tries: usize,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        Self {
            isolated_region: DropRegion::default(),
            ranked_grasps: 3,
            max_consecutive_failures: 3,
            end_round_without_grasp: true,
            failed_grasp_radius_m: 0.02,
            failed_grasp_angle_deg: 15.0,
            clutter_objects: 5,
            clutter_center_xy_m: [0.05, -0.52],
            packed_start_m: 0.30,
            packed_step_m: 0.01,
            pile_spread_m: 0.025,
            pile_box_m: [0.30, 0.45],
            pile_box_height_m: 0.15,
            pile_drop_gap_m: 0.02,
            max_attempts_per_round: 20,
            scattered_half_extent_m: 0.18,
            scattered_clearance_m: 0.04,
            scattered_tries: 50,
        }
    }
}

impl ScenarioConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), WorldError> {
        let bad = |field: &str, reason: String| {
            Err(WorldError::InvalidConfig {
                field: format!("scenario.{field}"),
                reason,
            })
        };
        for (field, v) in [
            ("ranked_grasps", self.ranked_grasps),
            ("max_consecutive_failures", self.max_consecutive_failures),
            ("clutter_objects", self.clutter_objects),
            ("max_attempts_per_round", self.max_attempts_per_round),
            ("scattered_tries", self.scattered_tries),
        ] {
            if v == 0 {
                return bad(field, "must be at least 1".into());
            }
        }
        for (field, v) in [
            ("packed_start_m", self.packed_start_m),
            ("packed_step_m", self.packed_step_m),
            ("pile_spread_m", self.pile_spread_m),
            ("pile_box_m[0]", self.pile_box_m[0]),
            ("pile_box_m[1]", self.pile_box_m[1]),
            ("pile_box_height_m", self.pile_box_height_m),
            ("pile_drop_gap_m", self.pile_drop_gap_m),
            ("scattered_half_extent_m", self.scattered_half_extent_m),
            ("scattered_clearance_m", self.scattered_clearance_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("{v} must be positive and finite"));
            }
        }
        if !(self.failed_grasp_radius_m.is_finite() && self.failed_grasp_radius_m >= 0.0) {
            return bad(
                "failed_grasp_radius_m",
                format!(
                    "{} must be zero (off) or positive and finite",
                    self.failed_grasp_radius_m
                ),
            );
        }
        if !(0.0..=90.0).contains(&self.failed_grasp_angle_deg) {
            return bad(
                "failed_grasp_angle_deg",
                format!(
                    "{} must be between 0 and 90 degrees",
                    self.failed_grasp_angle_deg
                ),
            );
        }
        if !self.clutter_center_xy_m.iter().all(|v| v.is_finite()) {
            return bad("clutter_center_xy_m", "must be finite".into());
        }
        Ok(())
    }

    /// Objects a round of `scenario` puts on the table.
    pub fn objects_per_round(&self, scenario: Scenario) -> usize {
        match scenario {
            Scenario::Isolated => 1,
            Scenario::Packed | Scenario::Pile | Scenario::Scattered => self.clutter_objects,
        }
    }
}

/// An object on the table in a round: its world handle and who it is.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedObject {
    /// The handle in the world.
    pub handle: ObjectHandle,
    /// Index into the library.
    pub library_index: usize,
    /// Its name in the world (the instance name, `#2` appended for a repeat).
    pub name: String,
    /// Its category.
    pub category: String,
    /// Its resting pose after the table was set.
    pub rest_pose: Pose,
}

/// Library indices of the objects round `round` shows: for the isolated scenario the library
/// taken category by category in turn; for packed and pile a seeded draw without replacement
/// (with replacement once the library is exhausted).
pub fn round_objects<R: Rng + ?Sized>(
    scenario: Scenario,
    library: &[ObjectModel],
    round: usize,
    config: &ScenarioConfig,
    rng: &mut R,
) -> Vec<usize> {
    let all: Vec<usize> = (0..library.len()).collect();
    round_objects_among(scenario, library, &all, round, config, rng)
}

/// [`round_objects`] drawing only from the library indices in `pool` (e.g. the categories that
/// have arrived by this round): isolated rounds take the pool's objects in the library's
/// category-by-category order, packed and pile rounds draw from the pool. With every index in
/// `pool` it is [`round_objects`], draw for draw.
pub fn round_objects_among<R: Rng + ?Sized>(
    scenario: Scenario,
    library: &[ObjectModel],
    pool: &[usize],
    round: usize,
    config: &ScenarioConfig,
    rng: &mut R,
) -> Vec<usize> {
    let pool: Vec<usize> = pool
        .iter()
        .copied()
        .filter(|&i| i < library.len())
        .collect();
    if pool.is_empty() {
        return Vec::new();
    }
    match scenario {
        Scenario::Isolated => {
            let order: Vec<usize> = interleaved_order(library)
                .into_iter()
                .filter(|i| pool.contains(i))
                .collect();
            vec![order[round % order.len()]]
        }
        Scenario::Packed | Scenario::Pile | Scenario::Scattered => {
            let mut left = pool.clone();
            let mut out = Vec::with_capacity(config.clutter_objects);
            for _ in 0..config.clutter_objects {
                if left.is_empty() {
                    left = pool.clone();
                }
                let k = rng.random_range(0..left.len());
                out.push(left.swap_remove(k));
            }
            out
        }
    }
}

/// The library's indices taken category by category in turn (categories in order of first
/// appearance): the first instance of every category, then the second, …
pub fn interleaved_order(library: &[ObjectModel]) -> Vec<usize> {
    let mut categories: Vec<&str> = Vec::new();
    for o in library {
        if !categories.contains(&o.category.as_str()) {
            categories.push(&o.category);
        }
    }
    let groups: Vec<Vec<usize>> = categories
        .iter()
        .map(|c| {
            (0..library.len())
                .filter(|&i| library[i].category == *c)
                .collect()
        })
        .collect();
    let longest = groups.iter().map(Vec::len).max().unwrap_or(0);
    let mut out = Vec::with_capacity(library.len());
    for k in 0..longest {
        for g in &groups {
            if let Some(&i) = g.get(k) {
                out.push(i);
            }
        }
    }
    out
}

fn uniform_yaw<R: Rng + ?Sized>(rng: &mut R) -> Rotation3<f32> {
    let yaw = rng.random_range(0.0_f32..std::f32::consts::PI);
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw).to_rotation_matrix()
}

/// Whether object `a` at `pose_a` and object `b` at its current pose intersect (their hulls).
fn hulls_intersect(
    world: &World,
    a: ObjectHandle,
    pose_a: &Pose,
    b: ObjectHandle,
) -> Result<bool, WorldError> {
    let ca = &world.physics.colliders[world.object_collider(a)?];
    let cb = &world.physics.colliders[world.object_collider(b)?];
    let pa = pose_to_rapier(pose_a).ok_or_else(|| WorldError::NonFinitePose {
        what: "packed placement".into(),
    })?;
    let pb = pose_to_rapier(&world.object_pose(b)?).ok_or_else(|| WorldError::NonFinitePose {
        what: "packed placement".into(),
    })?;
    Ok(intersection_test(&pa, ca.shape(), &pb, cb.shape()).map_or(true, |i| i.intersecting))
}

/// Distance between object `a` at `pose_a` and object `b` at its current pose (their
/// colliders; 0 when they touch).
fn collider_distance(
    world: &World,
    a: ObjectHandle,
    pose_a: &Pose,
    b: ObjectHandle,
) -> Result<f32, WorldError> {
    let ca = &world.physics.colliders[world.object_collider(a)?];
    let cb = &world.physics.colliders[world.object_collider(b)?];
    let non_finite = || WorldError::NonFinitePose {
        what: "scattered placement".into(),
    };
    let pa = pose_to_rapier(pose_a).ok_or_else(non_finite)?;
    let pb = pose_to_rapier(&world.object_pose(b)?).ok_or_else(non_finite)?;
    Ok(distance(&pa, ca.shape(), &pb, cb.shape()).map_or(0.0, |d| d.distance))
}

/// Sets the table for one round: spawns `picks` (library indices) as `scenario` arranges them,
/// each with its collider shape from `shapes`, and settles the scene. Returns the objects with
/// their resting poses, in spawn order.
pub fn set_table<R: Rng + ?Sized>(
    world: &mut World,
    scenario: Scenario,
    library: &[ObjectModel],
    shapes: &mut LibraryShapes,
    picks: &[usize],
    config: &ScenarioConfig,
    rng: &mut R,
) -> Result<Vec<PlacedObject>, WorldError> {
    config.validate()?;
    let mut table = TableSetting {
        world,
        library,
        shapes,
        config,
        spawned: Vec::new(),
    };
    match scenario {
        Scenario::Isolated => table.isolated(picks, rng)?,
        Scenario::Packed => table.packed(picks, rng)?,
        Scenario::Scattered => table.scattered(picks, rng)?,
        Scenario::Pile => table.pile(picks, rng)?,
    }
    table.placed()
}

/// A table being set for a round: the world, where the objects come from, and what has been
/// spawned so far. One method per scenario.
struct TableSetting<'a> {
    world: &'a mut World,
    library: &'a [ObjectModel],
    shapes: &'a mut LibraryShapes,
    config: &'a ScenarioConfig,
    /// The objects spawned so far, in spawn order: handle, library index, name.
    spawned: Vec<(ObjectHandle, usize, String)>,
}

impl TableSetting<'_> {
    /// The name of the next object from library index `index`: the instance name, `#2`, `#3`, …
    /// appended for a repeat.
    fn name_of(&self, index: usize) -> String {
        let base = self.library[index].name.clone();
        let repeats = self.spawned.iter().filter(|s| s.1 == index).count();
        if repeats == 0 {
            base
        } else {
            format!("{base}#{}", repeats + 1)
        }
    }

    /// Height of the table top (m).
    fn top_z_m(&self) -> f32 {
        self.world.config().table.top_z_m()
    }

    /// Spawns library object `index` as `name` at `pose` with its collider shape.
    fn spawn(&mut self, index: usize, name: &str, pose: &Pose) -> Result<ObjectHandle, WorldError> {
        self.shapes
            .spawn(self.world, index, name, &self.library[index], pose)
    }

    /// [`Scenario::Isolated`]: each pick dropped in the isolated region and settled.
    fn isolated<R: Rng + ?Sized>(
        &mut self,
        picks: &[usize],
        rng: &mut R,
    ) -> Result<(), WorldError> {
        for &i in picks {
            let name = self.name_of(i);
            let h = crate::physics::shapes::drop_object(
                self.shapes,
                self.world,
                i,
                &name,
                &self.library[i],
                &self.config.isolated_region,
                rng,
            )?;
            self.spawned.push((h, i, name));
        }
        Ok(())
    }

    /// [`Scenario::Packed`]: the first pick at the centre, the others slid in from the sides
    /// until they touch (see [`TableSetting::slide_in`]), then the scene settled.
    fn packed<R: Rng + ?Sized>(&mut self, picks: &[usize], rng: &mut R) -> Result<(), WorldError> {
        let center = self.config.clutter_center_xy_m;
        let top = self.top_z_m();
        for (k, &i) in picks.iter().enumerate() {
            let name = self.name_of(i);
            let rotation = uniform_yaw(rng);
            let at = |d: f32| packed_pose(center, top, k, d, rotation);
            // Spawn at the start, then slide in until touching, and back off one step.
            let start = if k == 0 {
                0.0
            } else {
                self.config.packed_start_m
            };
            let h = self.spawn(i, &name, &at(start))?;
            let d = if k > 0 {
                self.slide_in(h, start, &at)?
            } else {
                start
            };
            self.world.reset_object_pose(h, &at(d))?;
            self.spawned.push((h, i, name));
        }
        self.world.settle();
        Ok(())
    }

    /// The distance from the centre, from `start` down in [`ScenarioConfig::packed_step_m`]
    /// steps, at which object `h` placed by `at` last stood free of every object spawned so far
    /// (hull intersection tests, nothing moves).
    fn slide_in(
        &self,
        h: ObjectHandle,
        start: f32,
        at: &dyn Fn(f32) -> Pose,
    ) -> Result<f32, WorldError> {
        let mut d = start;
        let mut last_free = start;
        while d > 0.0 {
            let mut touching = false;
            for (other, _, _) in &self.spawned {
                if hulls_intersect(self.world, h, &at(d), *other)? {
                    touching = true;
                    break;
                }
            }
            if touching {
                break;
            }
            last_free = d;
            d -= self.config.packed_step_m;
        }
        Ok(last_free)
    }

    /// [`Scenario::Scattered`]: each pick upright at a uniform yaw, at a drawn position that
    /// keeps the clearance (see [`TableSetting::scattered_pose`]), then the scene settled.
    fn scattered<R: Rng + ?Sized>(
        &mut self,
        picks: &[usize],
        rng: &mut R,
    ) -> Result<(), WorldError> {
        let [cx, cy] = self.config.clutter_center_xy_m;
        let top = self.top_z_m();
        for &i in picks {
            let name = self.name_of(i);
            let rotation = uniform_yaw(rng);
            let at = |x: f32, y: f32| Pose::from_parts(Translation3::new(x, y, top), rotation);
            let h = self.spawn(i, &name, &at(cx, cy))?;
            if let Some(pose) = self.scattered_pose(h, &at, rng)? {
                self.world.reset_object_pose(h, &pose)?;
            }
            self.spawned.push((h, i, name));
        }
        self.world.settle();
        Ok(())
    }

    /// A pose for object `h` (placed at (x, y) by `at`): the first of up to
    /// [`ScenarioConfig::scattered_tries`] uniform draws that keeps the clearance to every object
    /// spawned so far, else the draw farthest from its nearest neighbour.
    fn scattered_pose<R: Rng + ?Sized>(
        &self,
        h: ObjectHandle,
        at: &dyn Fn(f32, f32) -> Pose,
        rng: &mut R,
    ) -> Result<Option<Pose>, WorldError> {
        let [cx, cy] = self.config.clutter_center_xy_m;
        let r = self.config.scattered_half_extent_m;
        let mut best: Option<(f32, Pose)> = None;
        for _ in 0..self.config.scattered_tries {
            let x = cx + r * rng.random_range(-1.0_f32..=1.0);
            let y = cy + r * rng.random_range(-1.0_f32..=1.0);
            let pose = at(x, y);
            let mut nearest = f32::INFINITY;
            for (other, _, _) in &self.spawned {
                nearest = nearest.min(collider_distance(self.world, h, &pose, *other)?);
            }
            if best.as_ref().is_none_or(|(d, _)| nearest > *d) {
                best = Some((nearest, pose));
            }
            if nearest >= self.config.scattered_clearance_m {
                break;
            }
        }
        Ok(best.map(|(_, pose)| pose))
    }

    /// [`Scenario::Pile`]: the picks dropped one after another into a temporary box, each
    /// settled; once the pile rests the box is swapped for the wider one, and that is removed
    /// once the pile rests again.
    fn pile<R: Rng + ?Sized>(&mut self, picks: &[usize], rng: &mut R) -> Result<(), WorldError> {
        let walls = self.pile_box(self.config.pile_box_m[0]);
        for &i in picks {
            let name = self.name_of(i);
            let pose = self.pile_drop_pose(i, rng)?;
            let h = self.spawn(i, &name, &pose)?;
            self.world.settle();
            self.spawned.push((h, i, name));
        }
        for wall in walls {
            self.world.remove_fixed_box(wall);
        }
        let wider = self.pile_box(self.config.pile_box_m[1]);
        self.world.settle();
        for wall in wider {
            self.world.remove_fixed_box(wall);
        }
        self.world.settle();
        Ok(())
    }

    /// Four fixed walls [`ScenarioConfig::pile_box_height_m`] high around a square of inner
    /// side `side_m` at the clutter centre.
    fn pile_box(&mut self, side_m: f32) -> Vec<ColliderHandle> {
        let [cx, cy] = self.config.clutter_center_xy_m;
        let top = self.top_z_m();
        let h = self.config.pile_box_height_m;
        let (inner, t) = (0.5 * side_m, 0.01f32);
        [
            (
                [cx + inner + t, cy, top + 0.5 * h],
                [t, inner + 2.0 * t, 0.5 * h],
            ),
            (
                [cx - inner - t, cy, top + 0.5 * h],
                [t, inner + 2.0 * t, 0.5 * h],
            ),
            (
                [cx, cy + inner + t, top + 0.5 * h],
                [inner + 2.0 * t, t, 0.5 * h],
            ),
            (
                [cx, cy - inner - t, top + 0.5 * h],
                [inner + 2.0 * t, t, 0.5 * h],
            ),
        ]
        .into_iter()
        .map(|(c, half)| {
            let mu = self.world.config().table.friction;
            self.world.add_fixed_box(Scenery::Wall, c, half, mu)
        })
        .collect()
    }

    /// Where library object `index` is released over the pile: a uniform orientation, a
    /// uniform position within ± [`ScenarioConfig::pile_spread_m`] of the centre, its lowest
    /// point [`ScenarioConfig::pile_drop_gap_m`] above the highest hull point of the pile so
    /// far (or the table).
    fn pile_drop_pose<R: Rng + ?Sized>(
        &self,
        index: usize,
        rng: &mut R,
    ) -> Result<Pose, WorldError> {
        let [cx, cy] = self.config.clutter_center_xy_m;
        let s = self.config.pile_spread_m;
        let rotation = uniform_rotation(rng);
        let x = cx + s * rng.random_range(-1.0_f32..=1.0);
        let y = cy + s * rng.random_range(-1.0_f32..=1.0);
        // Release above the pile so far.
        let mut pile_top = self.top_z_m();
        for (other, _, _) in &self.spawned {
            let pose = self.world.object_pose(*other)?;
            for p in self.world.object_hull_points_m(*other)? {
                pile_top = pile_top.max((pose * nalgebra::Point3::from(p)).z);
            }
        }
        let lowest = self.library[index]
            .mesh
            .vertices
            .iter()
            .map(|v| (rotation * Vector3::from(*v)).z)
            .fold(f32::INFINITY, f32::min);
        let lowest = if lowest.is_finite() { lowest } else { 0.0 };
        let z = pile_top + self.config.pile_drop_gap_m - lowest;
        Ok(Pose::from_parts(Translation3::new(x, y, z), rotation))
    }

    /// The spawned objects with their resting poses, in spawn order.
    fn placed(self) -> Result<Vec<PlacedObject>, WorldError> {
        let (world, library) = (&*self.world, self.library);
        self.spawned
            .into_iter()
            .map(|(handle, library_index, name)| {
                Ok(PlacedObject {
                    handle,
                    library_index,
                    category: library[library_index].category.clone(),
                    rest_pose: world.object_pose(handle)?,
                    name,
                })
            })
            .collect()
    }
}

/// Where packed object `k` stands at distance `d` from the centre (m) of the arrangement, with
/// `rotation`, on a table top at `top_z_m`: the first at the centre, the others coming from
/// +x, −x, +y, −y in turn; a fifth side object and beyond start from the diagonals.
fn packed_pose(
    center_xy_m: [f32; 2],
    top_z_m: f32,
    k: usize,
    d: f32,
    rotation: Rotation3<f32>,
) -> Pose {
    let sides = [[1.0f32, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]];
    let [cx, cy] = center_xy_m;
    let [dx, dy] = if k == 0 {
        [0.0, 0.0]
    } else {
        sides[(k - 1) % 4]
    };
    let ring = if k == 0 { 0.0 } else { ((k - 1) / 4) as f32 };
    let (dx, dy) = if ring > 0.0 {
        (dx - dy, dy + dx)
    } else {
        (dx, dy)
    };
    Pose::from_parts(
        Translation3::new(cx + dx * d, cy + dy * d, top_z_m),
        rotation,
    )
}

/// Checks that every library object can be simulated (its convex hull can be built) and can
/// land in every basket a run places objects in (`targets`, indices into the world's baskets;
/// the others are only scenery), naming the first that cannot: a basket whose shorter inner
/// side is below the object's smallest extent, or whose inner diagonal is below its middle one
/// (the extents of the mesh's bounding box), can never hold it, so a run would only record
/// drops.
pub fn check_library(
    world_config: &crate::physics::config::WorldConfig,
    library: &[ObjectModel],
    targets: &[usize],
) -> Result<(), WorldError> {
    let mut world = World::new(world_config.clone())?;
    let top = world_config.table.top_z_m();
    let [cx, cy, _] = world_config.table.center_m;
    for o in library {
        let pose = Pose::from_parts(Translation3::new(cx, cy, top), Rotation3::identity());
        let h = world.spawn_object(&o.name, &o.mesh, &pose)?;
        world.remove_object(h)?;
    }
    // After the table's check, which names an object too large for the table first.
    for o in library {
        let Some(mut extent) = mesh_extents_m(&o.mesh) else {
            continue;
        };
        extent.sort_by(f32::total_cmp);
        for &b in targets {
            let Some(basket) = world_config.baskets.get(b) else {
                continue;
            };
            let [ix, iy] = basket.inner_size_m;
            if extent[0] > ix.min(iy) || extent[1] > ix.hypot(iy) {
                return Err(WorldError::InvalidConfig {
                    field: format!("baskets[{b}].inner_size_m"),
                    reason: format!(
                        "{ix}×{iy} m cannot hold {} ({:.3}×{:.3}×{:.3} m): no way in",
                        o.name, extent[0], extent[1], extent[2]
                    ),
                });
            }
        }
    }
    Ok(())
}

/// The extents of a mesh's axis-aligned bounding box (m); `None` without vertices.
fn mesh_extents_m(mesh: &lgdm_pointcloud::mesh::Mesh) -> Option<[f32; 3]> {
    let first = *mesh.vertices.first()?;
    let (mut lo, mut hi) = (first, first);
    for v in &mesh.vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    Some([hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]])
}

/// Whether the object's centre of mass is still over the table top (not fallen off, not in a
/// basket).
pub fn on_table(world: &World, handle: ObjectHandle) -> Result<bool, WorldError> {
    let t = &world.config().table;
    let com = world.object_center_of_mass_m(handle)?;
    Ok((com[0] - t.center_m[0]).abs() <= 0.5 * t.size_m[0]
        && (com[1] - t.center_m[1]).abs() <= 0.5 * t.size_m[1]
        && com[2] > t.top_z_m() - 0.01)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::config::WorldConfig;
    use lgdm_pointcloud::objects::procedural_library;
    use rand::SeedableRng;

    /// A basket that cannot hold an object of the library is refused before any work, naming
    /// the basket's field and the object, when objects go into it; the default baskets hold
    /// every procedural object.
    #[test]
    fn a_basket_smaller_than_an_object_is_refused() {
        let library = procedural_library(&lgdm_pointcloud::objects::CATEGORIES, 1, 0).unwrap();
        let mut config = WorldConfig::default();
        check_library(&config, &library, &[0, 1]).unwrap();
        config.baskets[1].inner_size_m = [0.05, 0.3];
        match check_library(&config, &library, &[0, 1]) {
            Err(WorldError::InvalidConfig { field, reason }) => {
                assert_eq!(field, "baskets[1].inner_size_m");
                assert!(reason.contains("cannot hold"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        // A basket no object goes into is only scenery: a small one is fine.
        check_library(&config, &library, &[0]).unwrap();
    }

    /// The failed-grasp memory's radius and angle are refused negative or NaN, naming the field;
    /// radius 0 (off) is allowed.
    #[test]
    fn the_failed_grasp_memory_is_validated() {
        let field = |c: &ScenarioConfig| match c.validate() {
            Err(WorldError::InvalidConfig { field, .. }) => Some(field),
            _ => None,
        };
        for radius in [-0.01, f64::NAN, f64::INFINITY] {
            let c = ScenarioConfig {
                failed_grasp_radius_m: radius,
                ..ScenarioConfig::default()
            };
            assert_eq!(field(&c).as_deref(), Some("scenario.failed_grasp_radius_m"));
        }
        for angle in [-1.0, f64::NAN, 91.0] {
            let c = ScenarioConfig {
                failed_grasp_angle_deg: angle,
                ..ScenarioConfig::default()
            };
            assert_eq!(
                field(&c).as_deref(),
                Some("scenario.failed_grasp_angle_deg")
            );
        }
        let off = ScenarioConfig {
            failed_grasp_radius_m: 0.0,
            ..ScenarioConfig::default()
        };
        assert!(off.validate().is_ok());
    }

    /// Scattered objects stand apart, by the clearance, on the table and at rest.
    #[test]
    fn scattered_objects_keep_their_clearance() {
        let library =
            procedural_library(&["can", "mug", "apple", "glass", "bottle"], 1, 0).unwrap();
        let config = ScenarioConfig::default();
        for seed in 0..3 {
            let mut world = World::new(WorldConfig::default()).unwrap();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut shapes = LibraryShapes::hulls(library.len());
            let picks: Vec<usize> = (0..5).collect();
            let placed = set_table(
                &mut world,
                Scenario::Scattered,
                &library,
                &mut shapes,
                &picks,
                &config,
                &mut rng,
            )
            .unwrap();
            assert_eq!(placed.len(), 5);
            for (i, a) in placed.iter().enumerate() {
                assert!(on_table(&world, a.handle).unwrap());
                let pose = world.object_pose(a.handle).unwrap();
                for b in &placed[i + 1..] {
                    let d = collider_distance(&world, a.handle, &pose, b.handle).unwrap();
                    // Settling may move them by a millimetre or two.
                    assert!(
                        d > config.scattered_clearance_m - 0.005,
                        "seed {seed}: {} and {} {d} m apart",
                        a.name,
                        b.name
                    );
                }
            }
        }
    }
}
