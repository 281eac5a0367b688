//! Invariant: prediction is pure (same input, same output; the model is untouched) and
//! sequence-aware: contexts restart whenever the sequence id changes, so a sequence's
//! predictions do not depend on what was predicted before it, while continuing the same id
//! carries the temporal context over; `no_context` predicts from the input weights alone.

use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample};

fn rows() -> Vec<(Vec<f32>, u64, u32)> {
    (0..240u32)
        .map(|i| {
            let seq = i / 12;
            let c = seq % 4;
            let t = (i % 12) as f32;
            let x = vec![
                c as f32 * 1.5 + 0.15 * t,
                (c % 2) as f32 * 2.0 - 0.1 * t,
                ((i * 13) % 7) as f32 * 0.05,
            ];
            (x, seq as u64, c)
        })
        .collect()
}

fn model() -> Gdm {
    let rows = rows();
    let samples: Vec<Sample> = rows
        .iter()
        .map(|(x, s, c)| Sample::labelled(x, *s, *c, *c))
        .collect();
    let mut gdm = Gdm::new(GdmConfig::paper_batch(), 3).unwrap();
    for _ in 0..3 {
        gdm.train(&samples).unwrap();
        gdm.end_episode();
    }
    gdm
}

#[test]
fn prediction_is_pure() {
    let gdm = model();
    let before = gdm.to_bytes();
    let rows = rows();
    let samples: Vec<Sample> = rows
        .iter()
        .map(|(x, s, _)| Sample::unlabelled(x, *s))
        .collect();
    let a = gdm.predict(&samples, PredictOptions::default()).unwrap();
    let b = gdm.predict(&samples, PredictOptions::default()).unwrap();
    assert_eq!(a, b);
    assert_eq!(gdm.to_bytes(), before);
}

#[test]
fn contexts_restart_when_the_sequence_changes() {
    let gdm = model();
    let rows = rows();
    let a: Vec<Sample> = rows[24..36]
        .iter()
        .map(|(x, _, _)| Sample::unlabelled(x, 100))
        .collect();
    let b_new_id: Vec<Sample> = rows[48..60]
        .iter()
        .map(|(x, _, _)| Sample::unlabelled(x, 101))
        .collect();
    let b_same_id: Vec<Sample> = rows[48..60]
        .iter()
        .map(|(x, _, _)| Sample::unlabelled(x, 100))
        .collect();
    let opts = PredictOptions::default();
    let alone = gdm.predict(&b_new_id, opts).unwrap();
    let after_a: Vec<Sample> = a.iter().chain(&b_new_id).copied().collect();
    let after_a = gdm.predict(&after_a, opts).unwrap();
    assert_eq!(
        &after_a[12..],
        &alone[..],
        "a new sequence id must reset the contexts"
    );
    let continued: Vec<Sample> = a.iter().chain(&b_same_id).copied().collect();
    let continued = gdm.predict(&continued, opts).unwrap();
    assert_ne!(
        continued[12].activation, alone[0].activation,
        "the same id continues the sequence: the first view of b sees a's context"
    );
}

#[test]
fn no_context_uses_the_input_weights_only() {
    let gdm = model();
    let rows = rows();
    let samples: Vec<Sample> = rows
        .iter()
        .map(|(x, s, _)| Sample::unlabelled(x, *s))
        .collect();
    let with = gdm.predict(&samples, PredictOptions::default()).unwrap();
    let without = gdm
        .predict(&samples, PredictOptions { no_context: true })
        .unwrap();
    assert_ne!(with, without);
    // Without context the order of the samples does not matter.
    let reversed: Vec<Sample> = samples.iter().rev().copied().collect();
    let mut back = gdm
        .predict(&reversed, PredictOptions { no_context: true })
        .unwrap();
    back.reverse();
    assert_eq!(back, without);
    // The trained model recognises its training data either way.
    let labelled: Vec<Sample> = rows
        .iter()
        .map(|(x, s, c)| Sample::labelled(x, *s, *c, *c))
        .collect();
    for opts in [
        PredictOptions::default(),
        PredictOptions { no_context: true },
    ] {
        let scores = gdm.evaluate(&labelled, opts).unwrap();
        println!("{opts:?}: {scores:?}");
        assert!(scores.category_accuracy_em > 0.9, "{scores:?}");
        assert!(scores.category_accuracy_sm > 0.9, "{scores:?}");
    }
}
