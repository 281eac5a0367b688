//! The baselines (streaming LDA, nearest class mean) run through the same experiment as the GDM:
//! same plans and records, same seed ⇒ same bytes, replay refused, models saved with their
//! learner and refused by the GDM reader.

use lgdm_gdm::experiment::{Experiment, Scenario, Settings, Table};
use lgdm_gdm::learner::{Learner, LearnerKind, Model};
use lgdm_gdm::{CheckpointError, Gdm};

struct Data {
    x: Vec<f32>,
    collection: Vec<u32>,
    category: Vec<u32>,
    instance: Vec<u32>,
    sequence: Vec<u64>,
    frame: Vec<u32>,
    names: Vec<String>,
}

/// 4 collections (3 train, 1 test) × 3 categories × 3 instances × 5 frames of 3-d features.
fn data() -> Data {
    let mut d = Data {
        x: vec![],
        collection: vec![],
        category: vec![],
        instance: vec![],
        sequence: vec![],
        frame: vec![],
        names: vec!["mug".into(), "bowl".into(), "can".into()],
    };
    for c in 0..4u32 {
        for i in 0..9u32 {
            for f in 0..5u32 {
                let cat = i / 3;
                let wobble = 0.05 * ((c * 7 + i * 3 + f * 5) % 11) as f32;
                d.x.extend([
                    cat as f32 + wobble,
                    0.3 * (i % 3) as f32 - wobble,
                    0.1 * f as f32,
                ]);
                d.collection.push(c);
                d.category.push(cat);
                d.instance.push(i);
                d.sequence.push(u64::from(c * 100 + i));
                d.frame.push(f);
            }
        }
    }
    d
}

fn table(d: &Data) -> Table<'_> {
    Table {
        features: &d.x,
        dim: 3,
        collection: &d.collection,
        category: &d.category,
        instance: &d.instance,
        sequence: &d.sequence,
        frame: &d.frame,
        train_collections: &[0, 1, 2],
        test_collections: &[3],
        category_names: &d.names,
        instance_names: &[],
    }
}

#[test]
fn baselines_run_every_scenario_deterministically_with_the_gdms_records() {
    let d = data();
    for learner in [LearnerKind::Slda, LearnerKind::Ncm] {
        for scenario in [Scenario::Ni, Scenario::Nc, Scenario::Batch] {
            let mut settings = Settings::for_learner(scenario, learner);
            settings.trials = 2;
            settings.epochs = 2;
            assert!(!settings.replay);
            let experiment = Experiment::new(table(&d), settings).unwrap();
            let one = experiment.run(1, &|_| {}).unwrap();
            let two = experiment.run(2, &|_| {}).unwrap();
            let gdm_plan = {
                let s = Settings {
                    epochs: 2,
                    ..Settings::new(scenario)
                };
                Experiment::new(table(&d), s).unwrap().plan(1)
            };
            assert_eq!(
                format!("{:?}", experiment.plan(1)),
                format!("{gdm_plan:?}"),
                "the GDM's plans"
            );
            for ((m1, r1), (m2, r2)) in one.iter().zip(&two) {
                assert_eq!(m1.kind(), learner);
                assert_eq!(m1.to_bytes(), m2.to_bytes(), "same seed, same bytes");
                let strip = |r: &lgdm_gdm::experiment::TrialRecord| {
                    let mut r = r.clone();
                    r.train_seconds = 0.0;
                    r.inference_ms_per_sample = 0.0;
                    r.steps.iter_mut().for_each(|s| s.seconds = 0.0);
                    serde_json::to_string(&r).unwrap()
                };
                assert_eq!(strip(r1), strip(r2));
                assert_eq!(r1.episodic_nodes, m1.nodes().0);
                assert_eq!(r1.model_size_bytes, m1.to_bytes().len());
            }
            let records = one.into_iter().map(|(_, r)| r).collect();
            let metrics = experiment.metrics(records, "toy", "");
            assert_eq!(metrics.learner, learner);
            assert!(!metrics.context && !metrics.replay);
            // Well-separated categories: both baselines get them nearly all.
            let s = &metrics.summary;
            assert!(
                s.test_category_accuracy_sm.mean > 0.9,
                "{learner} {scenario}: {s:?}"
            );
            assert!(
                metrics
                    .to_json()
                    .contains(&format!("\"learner\": \"{learner}\""))
            );
        }
    }
}

#[test]
fn replay_is_refused_for_a_baseline_and_models_keep_their_learner() {
    let d = data();
    let mut settings = Settings::for_learner(Scenario::Ni, LearnerKind::Slda);
    settings.replay = true;
    let err = Experiment::new(table(&d), settings)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("replay applies to the gdm learner only"),
        "{err}"
    );
    assert!(err.contains("slda"), "{err}");

    let mut settings = Settings::for_learner(Scenario::Ni, LearnerKind::Ncm);
    settings.trials = 1;
    let experiment = Experiment::new(table(&d), settings).unwrap();
    let (model, _) = experiment.run(1, &|_| {}).unwrap().remove(0);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.lgdm");
    model.save(&path).unwrap();
    assert_eq!(Model::load(&path).unwrap(), model);
    let err = Gdm::load(&path).unwrap_err();
    assert!(
        matches!(&err, CheckpointError::OtherLearner { found, .. } if found == "ncm"),
        "{err}"
    );
    assert_eq!(
        err.to_string(),
        "a model of the ncm learner, not of the gdm learner"
    );
    assert!(model.into_gdm().is_none());
}
