//! Invariant: after any stream of training, episode ends and replays, both memories stay
//! structurally sound: edges symmetric with equal ages and no dangling or self edge, synapses
//! only between existing nodes, habituation in (0, 1], histogram counts finite and > 0, at least
//! 2 nodes, and a checkpoint round trip reproduces the model exactly.

use lgdm_gdm::{GammaGwr, Gdm, GdmConfig, Metric, PredictOptions, Sample};
use proptest::collection::vec;
use proptest::option;
use proptest::prelude::*;

const DIM: usize = 3;

fn assert_sound(net: &GammaGwr, what: &str) {
    net.check_consistency()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let n = net.len();
    assert!(n >= 2, "{what}: {n} nodes");
    for i in 0..n {
        let h = net.habituation(i);
        assert!(h > 0.0 && h <= 1.0, "{what}: node {i} habituation {h}");
        for e in net.edges(i) {
            let j = e.to as usize;
            assert!(j < n && j != i, "{what}: edge {i}–{j} dangling or self");
            assert_eq!(
                net.edge_age(j, i),
                Some(e.age),
                "{what}: edge {i}–{j} asymmetric"
            );
        }
        for &(j, c) in net.synapses(i) {
            assert!((j as usize) < n && c > 0, "{what}: synapse {i}→{j} ({c})");
        }
        for level in 0..net.levels() {
            for &(_, v) in net.histogram(level, i).entries() {
                assert!(
                    v.is_finite() && v > 0.0,
                    "{what}: node {i} histogram count {v}"
                );
            }
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum After {
    Nothing,
    EndEpisode,
    Replay,
    Both,
}

fn metric() -> impl Strategy<Value = Metric> {
    prop_oneof![
        Just(Metric::Manhattan),
        Just(Metric::Euclidean),
        Just(Metric::SquaredEuclidean),
        Just(Metric::Minkowski { p: 3.0 }),
        Just(Metric::Cosine),
        Just(Metric::Mahalanobis),
    ]
}

type Row = (Vec<f32>, u64, Option<u32>, Option<u32>);

fn rows() -> impl Strategy<Value = Vec<Row>> {
    vec(
        (
            vec(-2.0f32..2.0, DIM),
            0u64..4,
            option::of(0u32..6),
            option::of(prop_oneof![Just(0u32), Just(1), Just(u32::MAX)]),
        ),
        2..120,
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn memories_stay_sound_after_random_streams(
        rows in rows(),
        chunks in vec((1usize..40, prop_oneof![
            Just(After::Nothing), Just(After::EndEpisode), Just(After::Replay), Just(After::Both)
        ]), 1..6),
        a_t in 0.05f32..0.99,
        h_t in 0.1f32..1.0,
        n_t in prop_oneof![Just(0.2f32), Just(1.0)],
        max_age in 1u32..15,
        k in 0usize..3,
        metric in metric(),
    ) {
        let mut config = GdmConfig { metric, ..GdmConfig::paper_incremental() };
        for m in [&mut config.episodic, &mut config.semantic] {
            m.activation_threshold = a_t;
            m.habituation_threshold = h_t;
            m.removal_threshold = n_t;
            m.max_age = max_age;
            m.context_depth = k;
        }
        let mut gdm = Gdm::new(config, DIM).unwrap();
        let samples: Vec<Sample> = rows
            .iter()
            .map(|(x, s, i, c)| Sample { x, sequence: *s, instance: *i, category: *c })
            .collect();
        // The first batch holds at least the two initial samples.
        gdm.train(&samples[..2]).unwrap();
        let mut at = 2;
        for (len, after) in chunks {
            let end = (at + len).min(samples.len());
            if end > at {
                gdm.train(&samples[at..end]).unwrap();
                at = end;
            }
            match after {
                After::Nothing => {}
                After::EndEpisode => gdm.end_episode(),
                After::Replay => { gdm.replay().unwrap(); }
                After::Both => { gdm.end_episode(); gdm.replay().unwrap(); }
            }
            assert_sound(gdm.episodic().network(), "episodic");
            assert_sound(gdm.semantic().network(), "semantic");
        }
        let predictions = gdm.predict(&samples, PredictOptions::default()).unwrap();
        prop_assert_eq!(predictions.len(), samples.len());
        for p in &predictions {
            prop_assert!(p.activation > 0.0 && p.activation <= 1.0);
        }
        let restored = Gdm::from_bytes(&gdm.to_bytes()).unwrap();
        prop_assert!(restored == gdm);
    }
}
