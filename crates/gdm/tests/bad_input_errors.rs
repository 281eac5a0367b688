//! Invariant: bad input (NaN or infinite features, wrong dimension, empty batch, zero dimension,
//! invalid config, untrained model) gives a typed error saying what and where, never a panic,
//! and a rejected training batch leaves the model unchanged.

use lgdm_gdm::{ConfigError, Gdm, GdmConfig, GdmError, PredictOptions, Sample};

fn trained() -> Gdm {
    let xs: Vec<[f32; 3]> = (0..20).map(|i| [i as f32 * 0.1, 0.0, 1.0]).collect();
    let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, 0, 1, 2)).collect();
    let mut gdm = Gdm::new(GdmConfig::default(), 3).unwrap();
    gdm.train(&samples).unwrap();
    gdm
}

#[test]
fn non_finite_features_are_rejected_with_their_position() {
    let mut gdm = trained();
    let before = gdm.to_bytes();
    let good = [0.0, 0.0, 0.0];
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let x = [0.0, 1.0, bad];
        let batch = [Sample::unlabelled(&good, 0), Sample::unlabelled(&x, 0)];
        let want = |e: &GdmError| {
            matches!(
                e,
                GdmError::NonFinite {
                    sample: 1,
                    position: 2
                }
            )
        };
        let e = gdm.train(&batch).unwrap_err();
        assert!(want(&e), "{e}");
        let e = gdm.predict(&batch, PredictOptions::default()).unwrap_err();
        assert!(want(&e), "{e}");
        let e = gdm
            .evaluate(&batch, PredictOptions { no_context: true })
            .unwrap_err();
        assert!(want(&e), "{e}");
        assert!(e.to_string().contains("sample 1"), "{e}");
    }
    assert_eq!(
        gdm.to_bytes(),
        before,
        "a rejected batch must not train the model"
    );
}

#[test]
fn wrong_dimension_is_rejected() {
    let mut gdm = trained();
    let before = gdm.to_bytes();
    let good = [0.0, 0.0, 0.0];
    let short = [0.0, 0.0];
    let batch = [Sample::unlabelled(&good, 0), Sample::unlabelled(&short, 0)];
    let e = gdm.train(&batch).unwrap_err();
    assert!(
        matches!(
            e,
            GdmError::DimensionMismatch {
                sample: 1,
                expected: 3,
                found: 2
            }
        ),
        "{e}"
    );
    let e = gdm.predict(&batch, PredictOptions::default()).unwrap_err();
    assert!(matches!(e, GdmError::DimensionMismatch { .. }), "{e}");
    assert_eq!(gdm.to_bytes(), before);
}

#[test]
fn empty_batches_are_rejected() {
    let mut gdm = trained();
    assert!(matches!(gdm.train(&[]), Err(GdmError::EmptyBatch)));
    assert!(matches!(
        gdm.predict(&[], PredictOptions::default()),
        Err(GdmError::EmptyBatch)
    ));
    assert!(matches!(
        gdm.evaluate(&[], PredictOptions::default()),
        Err(GdmError::EmptyBatch)
    ));
}

#[test]
fn zero_dimension_and_bad_config_are_rejected() {
    assert!(matches!(
        Gdm::new(GdmConfig::default(), 0),
        Err(GdmError::ZeroDimension)
    ));
    let mut config = GdmConfig::default();
    config.semantic.epsilon_n = -1.0;
    match Gdm::new(config, 3) {
        Err(GdmError::Config(ConfigError::Invalid { field, .. })) => {
            assert_eq!(field, "semantic.epsilon_n")
        }
        other => panic!("expected a config error, got {other:?}"),
    }
}

#[test]
fn an_untrained_model_cannot_predict() {
    let gdm = Gdm::new(GdmConfig::default(), 3).unwrap();
    let x = [0.0, 0.0, 0.0];
    let e = gdm
        .predict(&[Sample::unlabelled(&x, 0)], PredictOptions::default())
        .unwrap_err();
    assert!(matches!(e, GdmError::NotTrained), "{e}");
    // Replay and episode ends on an empty model are harmless no-ops.
    let mut gdm = gdm;
    gdm.end_episode();
    assert_eq!(gdm.replay().unwrap().chains, 0);
}

#[test]
fn one_sample_is_enough_to_predict() {
    let mut gdm = Gdm::new(GdmConfig::default(), 3).unwrap();
    let x = [0.5, 0.5, 0.5];
    gdm.train(&[Sample::labelled(&x, 0, 4, 5)]).unwrap();
    let p = gdm
        .predict(&[Sample::unlabelled(&x, 0)], PredictOptions::default())
        .unwrap();
    assert_eq!(
        (p[0].instance, p[0].category_em, p[0].category),
        (Some(4), Some(5), Some(5))
    );
    assert_eq!(p[0].activation, 1.0);
}

#[test]
fn a_bare_network_rejects_bad_input_too() {
    use lgdm_gdm::{GammaGwr, MemoryParams, Metric, Supervision};
    let mut net = GammaGwr::new(MemoryParams::default(), Metric::Manhattan, 2, 1).unwrap();
    let e = net
        .train_step(&[1.0], &[None], Supervision::Unsupervised)
        .unwrap_err();
    assert!(
        matches!(
            e,
            GdmError::DimensionMismatch {
                expected: 2,
                found: 1,
                ..
            }
        ),
        "{e}"
    );
    let e = net
        .train_step(&[1.0, f32::INFINITY], &[Some(1)], Supervision::Regulated)
        .unwrap_err();
    assert!(matches!(e, GdmError::NonFinite { position: 1, .. }), "{e}");
    assert!(net.is_empty(), "rejected steps must not change the network");
    // Missing label levels count as unlabelled; extra ones are ignored.
    net.train_step(&[0.0, 0.0], &[], Supervision::Unsupervised)
        .unwrap();
    net.train_step(&[1.0, 0.0], &[Some(3), Some(4)], Supervision::Unsupervised)
        .unwrap();
    assert_eq!((net.label(0, 0), net.label(0, 1)), (None, Some(3)));
    assert!(matches!(
        GammaGwr::new(MemoryParams::default(), Metric::Manhattan, 0, 1),
        Err(GdmError::ZeroDimension)
    ));
}
