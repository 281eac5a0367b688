//! Invariant: the same config, seed and data give the same model, byte for byte; how the data
//! are split into `train` calls does not matter; the seed drives the replay order.

use lgdm_gdm::{Gdm, GdmConfig, Sample};

fn data() -> Vec<(Vec<f32>, u64, u32)> {
    (0..300u32)
        .map(|i| {
            let c = i / 60;
            let t = (i % 20) as f32;
            let x = vec![
                c as f32 * 2.0 + 0.1 * t,
                ((i * 37) % 17) as f32 * 0.05,
                (c % 2) as f32 * 1.5 - 0.05 * t,
                ((i * 11) % 13) as f32 * 0.1,
            ];
            (x, (i / 20) as u64, c)
        })
        .collect()
}

fn samples(rows: &[(Vec<f32>, u64, u32)]) -> Vec<Sample<'_>> {
    rows.iter()
        .map(|(x, s, c)| Sample::labelled(x, *s, c * 3 + (*s % 3) as u32, *c))
        .collect()
}

fn trained(seed: u64, split: usize) -> Gdm {
    let rows = data();
    let samples = samples(&rows);
    let config = GdmConfig {
        seed,
        ..GdmConfig::paper_incremental()
    };
    let mut gdm = Gdm::new(config, 4).unwrap();
    for episode in samples.chunks(60) {
        let (a, b) = episode.split_at(split.min(episode.len()));
        if !a.is_empty() {
            gdm.train(a).unwrap();
        }
        if !b.is_empty() {
            gdm.train(b).unwrap();
        }
        gdm.end_episode();
        gdm.replay().unwrap();
    }
    gdm
}

#[test]
fn same_seed_same_bytes() {
    let a = trained(7, 60);
    let b = trained(7, 60);
    assert!(a.episodic().len() > 10, "the run should grow the network");
    assert_eq!(a.to_bytes(), b.to_bytes());
}

#[test]
fn batch_boundaries_do_not_change_the_model() {
    assert_eq!(trained(7, 60).to_bytes(), trained(7, 25).to_bytes());
}

#[test]
fn the_seed_drives_the_replay_order() {
    let a = trained(7, 60);
    let b = trained(8, 60);
    assert_ne!(a.episodic().network(), b.episodic().network());
}
