//! The paper's learning protocols as plans: which training sequences each learning step sees,
//! in what order, and what each step is evaluated on.
//!
//! A plan is built per trial from the rows' labels alone (collection, category, instance,
//! sequence, frame) and a seeded RNG, so the same seed gives the same plan.
//!
//! Definitions (also in docs/guide/training.md, "Scenarios"):
//! - **held-out instances**: in every trial, one instance per category (chosen at random, only
//!   where the category has at least two) is never trained on; its views in every collection
//!   form the "new instance" set (category accuracy only), in the training and test collections.
//! - **train rows**: the training collections (manifest split `train`, 12 of 15) of the other
//!   instances. **test rows**: the test collections (3 of 15) of the same instances.
//! - **batch**: E steps (epochs), each over all train rows; collections in an order shuffled
//!   per trial, sequences shuffled within a collection.
//! - **incremental**: one step per category (category order shuffled per trial); each step is
//!   evaluated on the train and test rows of every category seen so far.
//! - **ni**: the first training collection (in a per-trial shuffled order), then one training
//!   collection per step (12 steps).
//! - **nc**: categories in a shuffled order, steps of 4, 2, 2, 2 categories (all training
//!   collections); with other category counts: 4 first, then 2 at a time.
//! - **nic**: a first step with the sequences of 4 categories from the first training
//!   collection, then steps of 2 sequences each until every training sequence has been seen;
//!   the other categories enter the stream gradually (each at a random point in the first half
//!   of it). Steps = 1 + ceil(rest / 2).
//!
//! ni, nc and nic evaluate on the test rows of all categories, as the paper does.

use rand::seq::SliceRandom;
use rand::{Rng, RngExt};
use std::collections::{BTreeMap, BTreeSet};

/// A learning protocol of the paper.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scenario {
    /// All training collections, several epochs.
    Batch,
    /// One category per episode.
    Incremental,
    /// New instances: one training collection per step.
    Ni,
    /// New categories: 4, then 2 at a time.
    Nc,
    /// New instances and categories: small steps of two sequences.
    Nic,
}

impl Scenario {
    /// Every scenario, in the paper's order.
    pub const ALL: [Scenario; 5] = [
        Scenario::Batch,
        Scenario::Incremental,
        Scenario::Ni,
        Scenario::Nc,
        Scenario::Nic,
    ];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Batch => "batch",
            Scenario::Incremental => "incremental",
            Scenario::Ni => "ni",
            Scenario::Nc => "nc",
            Scenario::Nic => "nic",
        }
    }

    /// Whether intrinsic replay is on unless the user says otherwise.
    pub fn replay_by_default(self) -> bool {
        !matches!(self, Scenario::Batch)
    }

    /// The GDM preset this scenario uses unless the user says otherwise.
    pub fn default_preset(self) -> &'static str {
        match self {
            Scenario::Batch => "paper_batch",
            _ => "paper_incremental",
        }
    }

    /// Learning epochs per step unless the user says otherwise.
    pub fn default_epochs(self) -> usize {
        match self {
            Scenario::Batch => 35,
            _ => 1,
        }
    }
}

impl std::fmt::Display for Scenario {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Scenario {
    type Err = String;

    /// Parses a scenario name (`batch`, `incremental`, `ni`, `nc`, `nic`).
    fn from_str(s: &str) -> Result<Scenario, String> {
        Scenario::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Scenario::ALL.iter().map(|c| c.name()).collect();
                format!("unknown scenario {s:?} (one of {})", names.join(", "))
            })
    }
}

/// Labels of every row of a feature table, column-wise.
#[derive(Clone, Copy, Debug)]
pub struct Rows<'a> {
    /// Collection index of each row.
    pub collection: &'a [u32],
    /// Category id of each row.
    pub category: &'a [u32],
    /// Global instance id of each row.
    pub instance: &'a [u32],
    /// Sequence id of each row (one object in one collection).
    pub sequence: &'a [u64],
    /// Frame index of each row within its sequence.
    pub frame: &'a [u32],
}

impl Rows<'_> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.sequence.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.sequence.is_empty()
    }
}

/// What a step is evaluated on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EvalScope {
    /// Every category.
    All,
    /// Only the categories seen so far.
    SeenCategories,
}

/// One learning step (an epoch of batch learning, or an episode / mini-batch).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Step {
    /// Human-readable description ("collection 4", "categories mug, bowl", ...).
    pub label: String,
    /// Training sequences of this step, in presentation order; each is a list of row indices
    /// in frame order.
    pub sequences: Vec<Vec<usize>>,
}

/// The plan of one trial.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Learning steps in order.
    pub steps: Vec<Step>,
    /// What the steps are evaluated on.
    pub scope: EvalScope,
    /// Test rows (held-out collections, trained instances), sequences in order.
    pub test: Vec<Vec<usize>>,
    /// Rows of the held-out instances (every collection), sequences in order.
    pub new_instance: Vec<Vec<usize>>,
    /// The held-out instance ids (in validation mode: the validation instances).
    pub held_out_instances: Vec<u32>,
    /// Validation mode only: the trial's test held-out instances, whose rows the plan leaves
    /// out entirely (neither trained nor scored), so that nothing chosen on validation has seen
    /// them. Empty otherwise.
    pub excluded_instances: Vec<u32>,
}

/// Builds a trial's plan.
///
/// `train_collections` and `test_collections` come from the manifest's split;
/// `category_names` gives the step labels. The RNG draws the held-out instances first, then
/// the scenario's orders.
///
/// With `validate`, the held-out instances drawn first (the ones the same seed holds out for
/// the test) are left out entirely, and a second draw among the other instances (categories
/// with at least two left) gives the validation instances that play the held-out role; the
/// caller passes validation collections as the test collections.
#[allow(clippy::too_many_arguments)]
pub fn plan(
    scenario: Scenario,
    rows: Rows<'_>,
    train_collections: &[u32],
    test_collections: &[u32],
    category_names: &[String],
    epochs: usize,
    validate: bool,
    rng: &mut impl Rng,
) -> Plan {
    let mut sequences = sequences_in_frame_order(rows);
    let mut held_out_instances = draw_held_out_instances(rows, &BTreeSet::new(), rng);
    let mut excluded_instances = Vec::new();
    if validate {
        let excluded: BTreeSet<u32> = held_out_instances.iter().copied().collect();
        sequences.retain(|s| !excluded.contains(&rows.instance[s[0]]));
        held_out_instances = draw_held_out_instances(rows, &excluded, rng);
        excluded_instances = excluded.into_iter().collect();
    }
    let split = split_sequences(
        rows,
        &sequences,
        &held_out_instances,
        train_collections,
        test_collections,
    );
    let train = TrainSet {
        rows,
        sequences: split.train,
        category_names,
    };
    let categories = train.categories();
    let mut collections: Vec<u32> = train_collections.to_vec();
    collections.sort_unstable();
    collections.dedup();
    let (steps, scope) = match scenario {
        Scenario::Batch => (train.batch_steps(collections, epochs, rng), EvalScope::All),
        Scenario::Incremental => (
            train.incremental_steps(categories, rng),
            EvalScope::SeenCategories,
        ),
        Scenario::Ni => (train.ni_steps(collections, rng), EvalScope::All),
        Scenario::Nc => (train.nc_steps(categories, rng), EvalScope::All),
        Scenario::Nic => (
            train.nic_steps(categories, collections, rng),
            EvalScope::All,
        ),
    };
    Plan {
        steps,
        scope,
        test: split.test,
        new_instance: split.new_instance,
        held_out_instances,
        excluded_instances,
    }
}

/// The rows grouped into sequences (in sequence-id order: deterministic), each in frame order.
fn sequences_in_frame_order(rows: Rows<'_>) -> Vec<Vec<usize>> {
    let mut by_sequence: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for i in 0..rows.len() {
        by_sequence.entry(rows.sequence[i]).or_default().push(i);
    }
    for seq in by_sequence.values_mut() {
        seq.sort_by_key(|&i| rows.frame[i]);
    }
    by_sequence.into_values().collect()
}

/// One held-out instance per category with at least two instances besides `excluded`
/// (categories in id order, drawn uniformly among the category's other instance ids).
fn draw_held_out_instances(
    rows: Rows<'_>,
    excluded: &BTreeSet<u32>,
    rng: &mut impl Rng,
) -> Vec<u32> {
    let mut instances_of: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
    for i in (0..rows.len()).filter(|&i| !excluded.contains(&rows.instance[i])) {
        instances_of
            .entry(rows.category[i])
            .or_default()
            .insert(rows.instance[i]);
    }
    let mut held_out_instances = Vec::new();
    for set in instances_of.values() {
        if set.len() >= 2 {
            let list: Vec<u32> = set.iter().copied().collect();
            held_out_instances.push(list[rng.random_range(0..list.len())]);
        }
    }
    held_out_instances
}

/// A trial's sequences by role.
struct Split<'s> {
    /// The trained instances' sequences in the training collections.
    train: Vec<&'s Vec<usize>>,
    /// The trained instances' sequences in the test collections.
    test: Vec<Vec<usize>>,
    /// The held-out instances' sequences in either.
    new_instance: Vec<Vec<usize>>,
}

/// Splits `sequences` (in order) by the held-out instances and the collections.
fn split_sequences<'s>(
    rows: Rows<'_>,
    sequences: &'s [Vec<usize>],
    held_out_instances: &[u32],
    train_collections: &[u32],
    test_collections: &[u32],
) -> Split<'s> {
    let held: BTreeSet<u32> = held_out_instances.iter().copied().collect();
    let first = |s: &Vec<usize>| s[0];
    let is_held = |s: &Vec<usize>| held.contains(&rows.instance[first(s)]);
    let in_collections = |s: &Vec<usize>, cs: &[u32]| cs.contains(&rows.collection[first(s)]);

    let train: Vec<&Vec<usize>> = sequences
        .iter()
        .filter(|s| !is_held(s) && in_collections(s, train_collections))
        .collect();
    let test: Vec<Vec<usize>> = sequences
        .iter()
        .filter(|s| !is_held(s) && in_collections(s, test_collections))
        .cloned()
        .collect();
    // Held-out instances in the collections this run may use (all of them, except in
    // validation mode, where the caller passes validation collections as the test set).
    let new_instance: Vec<Vec<usize>> = sequences
        .iter()
        .filter(|s| {
            is_held(s)
                && (in_collections(s, train_collections) || in_collections(s, test_collections))
        })
        .cloned()
        .collect();
    Split {
        train,
        test,
        new_instance,
    }
}

/// The training sequences of a trial, and the steps each scenario makes of them.
struct TrainSet<'a> {
    rows: Rows<'a>,
    sequences: Vec<&'a Vec<usize>>,
    category_names: &'a [String],
}

impl TrainSet<'_> {
    fn category_of(&self, s: &[usize]) -> u32 {
        self.rows.category[s[0]]
    }

    fn collection_of(&self, s: &[usize]) -> u32 {
        self.rows.collection[s[0]]
    }

    /// The category's name for step labels (`category <id>` when it has none).
    fn category_name(&self, c: u32) -> String {
        self.category_names
            .get(c as usize)
            .cloned()
            .unwrap_or_else(|| format!("category {c}"))
    }

    /// The categories trained on, in id order.
    fn categories(&self) -> Vec<u32> {
        self.sequences
            .iter()
            .map(|s| self.category_of(s))
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect()
    }

    /// The training sequences matching `pred`, shuffled.
    fn pick(&self, pred: &dyn Fn(&Vec<usize>) -> bool, rng: &mut dyn rand::Rng) -> Vec<Vec<usize>> {
        let mut out: Vec<Vec<usize>> = self
            .sequences
            .iter()
            .filter(|s| pred(s))
            .map(|s| (*s).clone())
            .collect();
        out.shuffle(rng);
        out
    }

    /// Batch: `epochs` steps, each over every sequence (collections in a shuffled order,
    /// sequences shuffled within a collection; the same order every epoch).
    fn batch_steps(
        &self,
        mut collections: Vec<u32>,
        epochs: usize,
        rng: &mut impl Rng,
    ) -> Vec<Step> {
        collections.shuffle(rng);
        let mut all = Vec::new();
        for &c in &collections {
            all.extend(self.pick(&|s| self.collection_of(s) == c, rng));
        }
        (0..epochs.max(1))
            .map(|e| Step {
                label: format!("epoch {}", e + 1),
                sequences: all.clone(),
            })
            .collect()
    }

    /// Incremental: one step per category, in a shuffled order.
    fn incremental_steps(&self, mut categories: Vec<u32>, rng: &mut impl Rng) -> Vec<Step> {
        categories.shuffle(rng);
        categories
            .iter()
            .map(|&c| Step {
                label: self.category_name(c),
                sequences: self.pick(&|s| self.category_of(s) == c, rng),
            })
            .collect()
    }

    /// NI: one step per training collection, in a shuffled order.
    fn ni_steps(&self, mut collections: Vec<u32>, rng: &mut impl Rng) -> Vec<Step> {
        collections.shuffle(rng);
        collections
            .iter()
            .map(|&c| Step {
                label: format!("collection {c}"),
                sequences: self.pick(&|s| self.collection_of(s) == c, rng),
            })
            .collect()
    }

    /// NC: categories in a shuffled order, 4 in the first step, then 2 at a time.
    fn nc_steps(&self, mut categories: Vec<u32>, rng: &mut impl Rng) -> Vec<Step> {
        categories.shuffle(rng);
        let mut steps = Vec::new();
        let mut rest: &[u32] = &categories;
        let mut size = 4;
        while !rest.is_empty() {
            let take = size.min(rest.len());
            let (now, later) = rest.split_at(take);
            let names: Vec<String> = now.iter().map(|&c| self.category_name(c)).collect();
            steps.push(Step {
                label: names.join(", "),
                sequences: self.pick(&|s| now.contains(&self.category_of(s)), rng),
            });
            rest = later;
            size = 2;
        }
        steps
    }

    /// NIC: the sequences of 4 categories from the first collection (both in shuffled orders),
    /// then mini-batches of 2 sequences; each later category enters at a random point in the
    /// first half of the stream.
    fn nic_steps(
        &self,
        mut categories: Vec<u32>,
        mut collections: Vec<u32>,
        rng: &mut impl Rng,
    ) -> Vec<Step> {
        categories.shuffle(rng);
        collections.shuffle(rng);
        let first_cats: Vec<u32> = categories.iter().take(4).copied().collect();
        let first_coll = collections.first().copied();
        let in_first = |s: &Vec<usize>| {
            first_cats.contains(&self.category_of(s)) && Some(self.collection_of(s)) == first_coll
        };
        let mut steps = vec![Step {
            label: format!(
                "categories {} (collection {})",
                first_cats
                    .iter()
                    .map(|&c| self.category_name(c))
                    .collect::<Vec<_>>()
                    .join(", "),
                first_coll.unwrap_or(0)
            ),
            sequences: self.pick(&in_first, rng),
        }];
        // Each later category enters at a random point in the first half of the stream.
        let entry: BTreeMap<u32, f64> = categories
            .iter()
            .skip(4)
            .map(|&c| (c, rng.random_range(0.0..0.5)))
            .collect();
        let mut rest: Vec<(f64, Vec<usize>)> = self
            .sequences
            .iter()
            .filter(|s| !in_first(s))
            .map(|s| {
                let key: f64 = rng.random_range(0.0..1.0);
                let key = entry
                    .get(&self.category_of(s))
                    .map_or(key, |&e| e + key * (1.0 - e));
                (key, (*s).clone())
            })
            .collect();
        rest.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (k, pair) in rest.chunks(2).enumerate() {
            steps.push(Step {
                label: format!("mini-batch {}", k + 2),
                sequences: pair.iter().map(|(_, s)| s.clone()).collect(),
            });
        }
        steps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// 15 collections × 10 categories × 3 instances × 4 frames.
    struct Fixture {
        collection: Vec<u32>,
        category: Vec<u32>,
        instance: Vec<u32>,
        sequence: Vec<u64>,
        frame: Vec<u32>,
    }

    fn fixture() -> Fixture {
        let mut f = Fixture {
            collection: vec![],
            category: vec![],
            instance: vec![],
            sequence: vec![],
            frame: vec![],
        };
        for c in 0..15u32 {
            for inst in 0..30u32 {
                for fr in 0..4u32 {
                    f.collection.push(c);
                    f.category.push(inst / 3);
                    f.instance.push(inst);
                    f.sequence.push(u64::from(c) * 1000 + u64::from(inst));
                    f.frame.push(3 - fr); // stored out of order on purpose
                }
            }
        }
        f
    }

    fn rows(f: &Fixture) -> Rows<'_> {
        Rows {
            collection: &f.collection,
            category: &f.category,
            instance: &f.instance,
            sequence: &f.sequence,
            frame: &f.frame,
        }
    }

    fn build(s: Scenario, seed: u64) -> (Fixture, Plan) {
        build_with(s, seed, false)
    }

    fn build_with(s: Scenario, seed: u64, validate: bool) -> (Fixture, Plan) {
        let f = fixture();
        let names: Vec<String> = (0..10).map(|c| format!("c{c}")).collect();
        let train: Vec<u32> = (0..12).collect();
        let test: Vec<u32> = (12..15).collect();
        let p = plan(
            s,
            rows(&f),
            &train,
            &test,
            &names,
            3,
            validate,
            &mut ChaCha8Rng::seed_from_u64(seed),
        );
        (f, p)
    }

    fn trained_sequences(p: &Plan) -> BTreeSet<Vec<usize>> {
        p.steps
            .iter()
            .flat_map(|s| s.sequences.iter().cloned())
            .collect()
    }

    #[test]
    fn validation_never_reads_the_test_held_out_instances_and_holds_out_others() {
        for scenario in Scenario::ALL {
            for seed in 0..4 {
                let (_, normal) = build(scenario, seed);
                let (f, p) = build_with(scenario, seed, true);
                assert!(normal.excluded_instances.is_empty());
                // The instances the same seed holds out for the test are left out entirely.
                assert_eq!(p.excluded_instances, normal.held_out_instances);
                let excluded: BTreeSet<u32> = p.excluded_instances.iter().copied().collect();
                let every = p
                    .steps
                    .iter()
                    .flat_map(|s| &s.sequences)
                    .chain(&p.test)
                    .chain(&p.new_instance);
                for seq in every {
                    for &r in seq {
                        assert!(!excluded.contains(&f.instance[r]), "{scenario:?} {seed}");
                    }
                }
                // One validation instance per category, none of them a test one.
                assert_eq!(p.held_out_instances.len(), 10);
                let cats: BTreeSet<u32> = p.held_out_instances.iter().map(|i| i / 3).collect();
                assert_eq!(cats.len(), 10);
                assert!(p.held_out_instances.iter().all(|i| !excluded.contains(i)));
                assert!(!p.new_instance.is_empty());
                for seq in &p.new_instance {
                    assert!(p.held_out_instances.contains(&f.instance[seq[0]]));
                }
            }
        }
    }

    #[test]
    fn held_out_instances_are_never_trained_and_one_per_category() {
        for s in [
            Scenario::Batch,
            Scenario::Incremental,
            Scenario::Ni,
            Scenario::Nc,
            Scenario::Nic,
        ] {
            let (f, p) = build(s, 7);
            assert_eq!(p.held_out_instances.len(), 10);
            let cats: BTreeSet<u32> = p.held_out_instances.iter().map(|&i| i / 3).collect();
            assert_eq!(cats.len(), 10);
            for step in &p.steps {
                for seq in &step.sequences {
                    assert!(!p.held_out_instances.contains(&f.instance[seq[0]]));
                    assert!(
                        f.collection[seq[0]] < 12,
                        "{s:?} trains on a test collection"
                    );
                }
            }
            for seq in &p.test {
                assert!(f.collection[seq[0]] >= 12);
            }
            assert_eq!(p.new_instance.len(), 15 * 10);
        }
    }

    #[test]
    fn sequences_are_in_frame_order() {
        let (f, p) = build(Scenario::Ni, 1);
        for seq in p.steps.iter().flat_map(|s| &s.sequences) {
            let frames: Vec<u32> = seq.iter().map(|&i| f.frame[i]).collect();
            assert_eq!(frames, vec![0, 1, 2, 3]);
        }
    }

    #[test]
    fn every_scenario_but_batch_trains_each_sequence_exactly_once() {
        for s in [
            Scenario::Incremental,
            Scenario::Ni,
            Scenario::Nc,
            Scenario::Nic,
        ] {
            let (_, p) = build(s, 3);
            let total: usize = p.steps.iter().map(|s| s.sequences.len()).sum();
            assert_eq!(total, 12 * 20, "{s:?}");
            assert_eq!(trained_sequences(&p).len(), 12 * 20, "{s:?}");
        }
    }

    #[test]
    fn step_shapes_match_the_protocols() {
        let (f, p) = build(Scenario::Batch, 2);
        assert_eq!(p.steps.len(), 3);
        assert_eq!(p.steps[0].sequences.len(), 240);

        let (f2, p) = build(Scenario::Incremental, 2);
        assert_eq!(p.steps.len(), 10);
        for step in &p.steps {
            let cats: BTreeSet<u32> = step.sequences.iter().map(|s| f2.category[s[0]]).collect();
            assert_eq!(cats.len(), 1);
        }
        assert_eq!(p.scope, EvalScope::SeenCategories);

        let (f3, p) = build(Scenario::Ni, 2);
        assert_eq!(p.steps.len(), 12);
        for step in &p.steps {
            let colls: BTreeSet<u32> = step.sequences.iter().map(|s| f3.collection[s[0]]).collect();
            assert_eq!(colls.len(), 1);
        }

        let (f4, p) = build(Scenario::Nc, 2);
        let sizes: Vec<usize> = p
            .steps
            .iter()
            .map(|st| {
                st.sequences
                    .iter()
                    .map(|s| f4.category[s[0]])
                    .collect::<BTreeSet<_>>()
                    .len()
            })
            .collect();
        assert_eq!(sizes, vec![4, 2, 2, 2]);

        let (f5, p) = build(Scenario::Nic, 2);
        let first: BTreeSet<u32> = p.steps[0]
            .sequences
            .iter()
            .map(|s| f5.category[s[0]])
            .collect();
        assert_eq!(first.len(), 4);
        assert_eq!(p.steps[0].sequences.len(), 8); // 4 categories × 2 trained instances
        assert!(p.steps[1..].iter().all(|s| s.sequences.len() <= 2));
        assert_eq!(p.steps.len(), 1 + (240 - 8usize).div_ceil(2));
        let _ = f;
    }

    #[test]
    fn same_seed_same_plan_other_seed_other_order() {
        let (_, a) = build(Scenario::Nic, 11);
        let (_, b) = build(Scenario::Nic, 11);
        let (_, c) = build(Scenario::Nic, 12);
        assert_eq!(a.steps, b.steps);
        assert_ne!(a.steps, c.steps);
    }
}
