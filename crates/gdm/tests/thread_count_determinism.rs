//! Trials run in parallel threads give the same models and records as trials run in turn:
//! `Experiment::run(jobs)` does not depend on `jobs`.

use lgdm_gdm::experiment::{Experiment, Scenario, Settings, Table, TrialRecord};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// 6 collections (4 train, 2 test) × 4 categories × 2 instances × 5 frames of 8-d features.
struct Data {
    x: Vec<f32>,
    collection: Vec<u32>,
    category: Vec<u32>,
    instance: Vec<u32>,
    sequence: Vec<u64>,
    frame: Vec<u32>,
    names: Vec<String>,
}

fn data() -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let noise = Normal::new(0.0f32, 0.05).unwrap();
    let mut d = Data {
        x: vec![],
        collection: vec![],
        category: vec![],
        instance: vec![],
        sequence: vec![],
        frame: vec![],
        names: (0..4).map(|c| format!("c{c}")).collect(),
    };
    for c in 0..6u32 {
        for i in 0..8u32 {
            for f in 0..5u32 {
                for k in 0..8u32 {
                    let centre = if k == i / 2 { 1.0 } else { 0.0 } + 0.2 * (i % 2) as f32;
                    d.x.push(centre + 0.02 * f as f32 + noise.sample(&mut rng));
                }
                d.collection.push(c);
                d.category.push(i / 2);
                d.instance.push(i);
                d.sequence.push(u64::from(c * 100 + i));
                d.frame.push(f);
            }
        }
    }
    d
}

/// Collections 0–3 train, 4–5 test.
fn table(d: &Data) -> Table<'_> {
    Table {
        features: &d.x,
        dim: 8,
        collection: &d.collection,
        category: &d.category,
        instance: &d.instance,
        sequence: &d.sequence,
        frame: &d.frame,
        train_collections: &[0, 1, 2, 3],
        test_collections: &[4, 5],
        category_names: &d.names,
        instance_names: &[],
    }
}

fn without_times(mut t: TrialRecord) -> TrialRecord {
    t.train_seconds = 0.0;
    t.inference_ms_per_sample = 0.0;
    for s in &mut t.steps {
        s.seconds = 0.0;
    }
    t
}

#[test]
fn parallel_trials_equal_sequential_trials() {
    let d = data();
    let table = table(&d);
    for scenario in [Scenario::Ni, Scenario::Nic] {
        let mut settings = Settings::new(scenario);
        settings.trials = 3;
        settings.seed = 9;
        let experiment = Experiment::new(table, settings).unwrap();
        let one = experiment.run(1, &|_| {}).unwrap();
        let two = experiment.run(2, &|_| {}).unwrap();
        assert_eq!(one.len(), 3);
        for ((g1, r1), (g2, r2)) in one.into_iter().zip(two) {
            assert_eq!(g1.to_bytes(), g2.to_bytes(), "{scenario}: models differ");
            assert_eq!(without_times(r1), without_times(r2), "{scenario}");
        }
    }
    // Trials differ from one another (each has its own seed).
    let experiment = Experiment::new(table, {
        let mut s = Settings::new(Scenario::Ni);
        s.trials = 2;
        s
    })
    .unwrap();
    let runs = experiment.run(2, &|_| {}).unwrap();
    assert_eq!((runs[0].1.seed, runs[1].1.seed), (0, 1));
    assert_ne!(runs[0].0.to_bytes(), runs[1].0.to_bytes());
}

#[test]
fn bad_settings_and_tables_are_refused_before_any_work() {
    let d = data();
    let table = table(&d);
    let refused = |table: Table<'_>, edit: &dyn Fn(&mut Settings)| {
        let mut s = Settings::new(Scenario::Ni);
        edit(&mut s);
        Experiment::new(table, s).unwrap_err().to_string()
    };
    assert!(refused(table, &|s| s.trials = 0).contains("trials"));
    assert!(refused(table, &|s| s.epochs = 0).contains("epochs"));
    assert!(refused(table, &|s| s.train_samples = 10).contains("batch"));
    let e = refused(table, &|s| {
        s.seed = u64::MAX;
        s.trials = 2
    });
    assert!(e.contains("overflow"), "{e}");
    let short = Table {
        frame: &d.frame[1..],
        ..table
    };
    assert!(refused(short, &|_| {}).contains("frame"));
    let mut nan = d.x.clone();
    nan[17] = f32::NAN;
    let e = refused(
        Table {
            features: &nan,
            ..table
        },
        &|_| {},
    );
    assert!(e.contains("row 2 column 1"), "{e}");
    let no_test = Table {
        test_collections: &[],
        ..table
    };
    assert!(refused(no_test, &|_| {}).contains("test collections"));
    let experiment = Experiment::new(table, Settings::new(Scenario::Ni)).unwrap();
    assert!(experiment.run(0, &|_| {}).is_err());
}
