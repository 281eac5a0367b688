//! Contract: in class-incremental learning (one class per episode, old classes never shown
//! again), intrinsic replay keeps the first classes recognisable: after the last episode their
//! semantic category accuracy is clearly higher with replay than without.
//!
//! The task: 10 classes in 16-D, each with 2 instances; an instance is a drifting Gaussian
//! trajectory (mean + linear drift over the sequence + noise), seen as several 20-view
//! sequences. Class means are close enough that classes overlap, so what the later episodes
//! learn competes with the earlier classes. Without replay, the semantic memory (which grows
//! only on its own errors) never learns to tell the early categories from the later ones: an
//! early category keeps the few nodes made while it was alone, and the later categories' nodes
//! take over its inputs; in the episodic memory, early-category nodes are relabelled by later
//! classes. Replaying RNATs shows the early categories again: the semantic memory errs on them
//! and grows nodes for them, and the episodic labels are reinforced.
//! Test data are fresh sequences (new noise) of the same instances.

use lgdm_gdm::{Gdm, GdmConfig, PredictOptions, Sample, Scores};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DIM: usize = 16;
const CLASSES: u32 = 10;
const INSTANCES: u32 = 2;
const VIEWS: u32 = 20;
const EPOCHS: usize = 3;
const OLD: u32 = 5;

struct Stream {
    xs: Vec<Vec<f32>>,
    sequence: Vec<u64>,
    instance: Vec<u32>,
    category: Vec<u32>,
}

impl Stream {
    fn samples(&self, keep: impl Fn(u32) -> bool) -> Vec<Sample<'_>> {
        (0..self.xs.len())
            .filter(|&i| keep(self.category[i]))
            .map(|i| {
                Sample::labelled(
                    &self.xs[i],
                    self.sequence[i],
                    self.instance[i],
                    self.category[i],
                )
            })
            .collect()
    }
}

/// Objects from `seed`; views with noise from `noise_seed`; `sequences` sequences per instance.
fn stream(seed: u64, noise_seed: u64, sequences: u32, first_sequence: u64) -> Stream {
    let (spread, drift, noise) = (0.05f32, 0.3f32, 0.1f32);
    let unit = Normal::new(0.0f32, 1.0).unwrap();
    let mut objects = ChaCha8Rng::seed_from_u64(seed);
    let mut views = ChaCha8Rng::seed_from_u64(noise_seed);
    let mut s = Stream {
        xs: Vec::new(),
        sequence: Vec::new(),
        instance: Vec::new(),
        category: Vec::new(),
    };
    let mut sequence = first_sequence;
    for c in 0..CLASSES {
        let class_mean: Vec<f32> = (0..DIM)
            .map(|_| spread * unit.sample(&mut objects))
            .collect();
        for i in 0..INSTANCES {
            let mean: Vec<f32> = class_mean
                .iter()
                .map(|m| m + 0.3 * spread * unit.sample(&mut objects))
                .collect();
            let direction: Vec<f32> = (0..DIM)
                .map(|_| drift * unit.sample(&mut objects))
                .collect();
            for _ in 0..sequences {
                sequence += 1;
                for t in 0..VIEWS {
                    let f = t as f32 / VIEWS as f32 - 0.5;
                    let x = (0..DIM)
                        .map(|k| mean[k] + f * direction[k] + noise * unit.sample(&mut views))
                        .collect();
                    s.xs.push(x);
                    s.sequence.push(sequence);
                    s.instance.push(c * INSTANCES + i);
                    s.category.push(c);
                }
            }
        }
    }
    s
}

/// Scores on the old classes and on the new ones after the last episode.
fn run(seed: u64, replay: bool) -> (Scores, Scores, usize, usize) {
    let train = stream(seed, 1000 + seed, 3, 0);
    let test = stream(seed, 2000 + seed, 2, 1_000_000);
    let config = GdmConfig {
        seed,
        ..GdmConfig::paper_incremental()
    };
    let mut gdm = Gdm::new(config, DIM).unwrap();
    for class in 0..CLASSES {
        let episode = train.samples(|c| c == class);
        for _ in 0..EPOCHS {
            gdm.train(&episode).unwrap();
        }
        gdm.end_episode();
        if replay {
            gdm.replay().unwrap();
        }
    }
    let opts = PredictOptions::default();
    let old = gdm.evaluate(&test.samples(|c| c < OLD), opts).unwrap();
    let new = gdm.evaluate(&test.samples(|c| c >= OLD), opts).unwrap();
    (old, new, gdm.episodic().len(), gdm.semantic().len())
}

#[test]
fn replay_keeps_the_first_classes_recognisable() {
    let mut gains = Vec::new();
    for seed in 0..3 {
        let (old_plain, new_plain, em_plain, sm_plain) = run(seed, false);
        let (old_replay, new_replay, em_replay, sm_replay) = run(seed, true);
        println!(
            "seed {seed}: classes 0-4 category accuracy SM {:.3} -> {:.3} with replay \
             (EM {:.3} -> {:.3}, instance {:.3} -> {:.3}); classes 5-9 SM {:.3} -> {:.3}; \
             nodes EM {em_plain} -> {em_replay}, SM {sm_plain} -> {sm_replay}",
            old_plain.category_accuracy_sm,
            old_replay.category_accuracy_sm,
            old_plain.category_accuracy_em,
            old_replay.category_accuracy_em,
            old_plain.instance_accuracy,
            old_replay.instance_accuracy,
            new_plain.category_accuracy_sm,
            new_replay.category_accuracy_sm,
        );
        let gain = old_replay.category_accuracy_sm - old_plain.category_accuracy_sm;
        assert!(
            gain > 0.1,
            "seed {seed}: replay should clearly help the old classes (gain {gain:.3})"
        );
        // Replay must not buy the old classes at the price of the new ones.
        assert!(new_replay.category_accuracy_sm > new_plain.category_accuracy_sm - 0.1);
        gains.push(gain);
    }
    let mean_gain = gains.iter().sum::<f64>() / gains.len() as f64;
    println!("mean gain on classes 0-4 (SM category accuracy): {mean_gain:.3}");
    assert!(mean_gain > 0.2, "mean gain {mean_gain:.3}");
}
