//! Any setup a user can type — within and far outside the documented limits — is either
//! prepared or refused with an error naming the setting; nothing panics, and preparing never
//! sets aside more than the limits allow (issue 22: the property test over sim setups).
//! Colliders are single hulls here so that each case stays fast; the decomposition is covered
//! by `setups.rs`.

use lgdm_sim::physics::shapes::ObjectShape;
use lgdm_sim::recognition::config::RecognitionConfig;
use lgdm_sim::recognition::error::RecognitionError;
use lgdm_sim::run::config::SimConfig;
use lgdm_sim::run::error::SimError;
use lgdm_sim::run::job::{GraspJob, GraspSetup, PickPlaceJob, PickPlaceSetup};
use lgdm_sim::run::objects::ObjectSource;
use lgdm_sim::run::spec::{MAX_ATTEMPTS, MAX_ROUNDS};
use lgdm_sim::tasks::scenario::Scenario;
use proptest::prelude::*;

/// The settings a refusal may name (the binary's options, without the dashes).
const SETTINGS: [&str; 9] = [
    "rounds",
    "attempts",
    "instances",
    "objects",
    "scenario",
    "targets",
    "arrive-after",
    "record",
    "model",
];

fn hulls() -> SimConfig {
    let mut config = SimConfig::default();
    config.shapes.shape = ObjectShape::Hull;
    config
}

fn scenario() -> impl Strategy<Value = Scenario> {
    prop_oneof![
        Just(Scenario::Isolated),
        Just(Scenario::Packed),
        Just(Scenario::Pile),
        Just(Scenario::Scattered)
    ]
}

/// Small counts that run, and the edges and far outside.
fn count(max: usize) -> impl Strategy<Value = usize> {
    prop_oneof![
        4 => 0usize..4,
        1 => Just(max),
        1 => Just(max + 1),
        1 => Just(usize::MAX),
    ]
}

/// Whether `r` is a preparation where every setting is valid (`wrong` empty), or a refusal
/// that names a setting: one of `wrong` when the case broke a rule of its own.
fn named(r: Result<(), SimError>, wrong: &[&str]) -> Result<(), TestCaseError> {
    match r {
        Ok(()) => {
            prop_assert!(wrong.is_empty(), "prepared although {wrong:?} are wrong");
            Ok(())
        }
        Err(SimError::Setting { name, .. }) => {
            prop_assert!(SETTINGS.contains(&name), "unknown setting {name}");
            prop_assert!(
                wrong.is_empty() || wrong.contains(&name),
                "refused naming {name}, but {wrong:?} are the wrong ones"
            );
            Ok(())
        }
        Err(SimError::Recognition(RecognitionError::InvalidConfig { field, .. })) => {
            prop_assert!(!field.is_empty());
            Ok(())
        }
        Err(other) => Err(TestCaseError::fail(format!(
            "a refusal that names no setting: {other}"
        ))),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn grasp_setups_are_prepared_or_refused_by_name(
        scenario in scenario(),
        rounds in count(MAX_ROUNDS),
        instances in count(100),
        seed in any::<u64>(),
    ) {
        // Only small valid runs are prepared for real: a valid large one is fine but slow.
        prop_assume!(rounds <= 3 || rounds > MAX_ROUNDS || instances == 0 || instances > 100);
        let setup = GraspSetup {
            scenario,
            rounds,
            seed,
            objects: Some(ObjectSource::Procedural { instances, seed }),
            config: hulls(),
            ..GraspSetup::default()
        };
        let prepared = GraspJob::prepare(setup);
        if let Ok(job) = &prepared {
            prop_assert!(job.spec().rounds <= MAX_ROUNDS);
            prop_assert!(job.library().objects.len() <= 10 * 100);
        }
        // Every rule of a grasp setup: a case that breaks none is prepared.
        let mut wrong = Vec::new();
        if rounds == 0 || rounds > MAX_ROUNDS {
            wrong.push("rounds");
        }
        if instances == 0 || instances > 100 {
            wrong.push("instances");
        }
        prop_assert_eq!(prepared.is_ok(), wrong.is_empty());
        named(prepared.map(|_| ()), &wrong)?;
    }

    #[test]
    fn pick_place_setups_are_prepared_or_refused_by_name(
        scenario in scenario(),
        rounds in proptest::option::of(count(MAX_ROUNDS)),
        attempts in proptest::option::of(count(MAX_ATTEMPTS)),
        set_size in prop_oneof![0usize..16, Just(51), Just(1_000_000)],
        targets in proptest::option::of(proptest::collection::vec(
            prop_oneof![Just("mug"), Just("can"), Just("apple"), Just("cup"), Just(" "), Just("")],
            0..3,
        )),
        arrive_after in proptest::option::of(0usize..5),
        confidence in prop_oneof![Just(0.6), Just(-1.0), Just(2.0), Just(f64::NAN)],
        seed in any::<u64>(),
    ) {
        let playable = match (rounds, attempts) {
            (Some(r), Some(a)) => r.min(a),
            (Some(r), None) => r,
            (None, Some(a)) => a,
            (None, None) => 10,
        };
        prop_assume!(playable <= 3 || playable > MAX_ROUNDS.min(MAX_ATTEMPTS));
        let setup = PickPlaceSetup {
            scenario,
            rounds,
            attempts,
            seed,
            set_size,
            recognition: RecognitionConfig {
                confidence_threshold: confidence,
                ..RecognitionConfig::default()
            },
            targets: targets.map(|t| t.into_iter().map(str::to_string).collect()),
            arrive_after,
            config: hulls(),
            ..PickPlaceSetup::default()
        };
        let prepared = PickPlaceJob::prepare(setup);
        if let Ok(job) = &prepared {
            prop_assert!(job.spec().rounds <= MAX_ROUNDS);
            prop_assert!(job.set().len() == set_size);
            prop_assert!(job.spec().packing.as_ref().is_none_or(|p| p
                .targets
                .iter()
                .all(|t| job.set().iter().any(|o| &o.category == t))));
        }
        // The rules every case can be checked against (the targets' depend on the set drawn):
        // a case that breaks one is refused.
        let mut wrong = Vec::new();
        if rounds.is_some_and(|r| r == 0 || r > MAX_ROUNDS) {
            wrong.push("rounds");
        }
        if attempts == Some(0) {
            wrong.push("attempts");
        }
        if set_size == 0 || set_size > 50 {
            wrong.push("objects");
        }
        if scenario == Scenario::Isolated {
            wrong.push("scenario");
        }
        let bad_confidence = !(0.0..=1.0).contains(&confidence);
        if !wrong.is_empty() || bad_confidence {
            prop_assert!(prepared.is_err(), "prepared although {wrong:?} are wrong");
        }
        // A refusal may name what this case cannot know beforehand (the targets against the
        // set drawn, the arrival) before the broken rule.
        if !wrong.is_empty() {
            wrong.extend(["targets", "arrive-after"]);
        }
        named(prepared.map(|_| ()), if bad_confidence { &[] } else { &wrong })?;
    }
}
