//! Training throughput and prediction latency at D = 256, K = 2 (paper_incremental, Manhattan)
//! for networks of 1k and 5k nodes.
//!
//! Networks are grown to their size first with a node cap (`max_nodes`) and an insertion-happy
//! threshold (a_T = 0.999, h_T = 1); once capped, every training step is a pure update (search,
//! habituation, weight, edge, neighbour, label and synapse updates), which is what is measured.
//!
//! `replay_clustered` and `replay_histograms` time one intrinsic replay of a 1k-node dual model
//! (throughput in replayed pseudo-samples); "histograms" = GOOD-like views (D = 675: three
//! 15 × 15 projections of drifting Gaussian blobs, each summing to 1).
//!
//! Data: "clustered" = 50 objects, each a 20-view sequence drifting around its own random centre
//! (like a turntable stream); "uniform" = i.i.d. uniform vectors, the worst case for the
//! early-abandoning search because all distances are alike.
//!
//! `gdm_790` is issue 42's cost check: the paper's network size (790 G-EM nodes, D = 256,
//! K = 2; clustered and uniform data) with a training step of one memory, and training and inference of the
//! dual model, per sample (the dual benches run batches of 200 samples; criterion's time is per
//! batch, so per sample = time / 200, or 1 / the reported throughput).
//!
//! Run: `cargo bench -p lgdm-gdm` (one core is used); `cargo bench -p lgdm-gdm -- 790` runs the
//! 790-node group only (the other groups' networks are then not grown).

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, BenchmarkId, Criterion, Throughput, criterion_group, criterion_main,
};
use lgdm_gdm::{GammaGwr, Gdm, GdmConfig, Metric, PredictOptions, Sample, Supervision};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DIM: usize = 256;
const VIEWS: usize = 20;

struct Data {
    xs: Vec<Vec<f32>>,
    sequence: Vec<u64>,
    label: Vec<u32>,
}

impl Data {
    fn split(&self, at: usize) -> (Data, Data) {
        let part = |r: std::ops::Range<usize>| Data {
            xs: self.xs[r.clone()].to_vec(),
            sequence: self.sequence[r.clone()].to_vec(),
            label: self.label[r].to_vec(),
        };
        (part(0..at), part(at..self.xs.len()))
    }

    fn samples(&self) -> Vec<Sample<'_>> {
        (0..self.xs.len())
            .map(|i| {
                Sample::labelled(
                    &self.xs[i],
                    self.sequence[i],
                    self.label[i],
                    self.label[i] % 10,
                )
            })
            .collect()
    }
}

fn clustered(n: usize, seed: u64) -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0f32, 1.0).unwrap();
    let centres: Vec<Vec<f32>> = (0..50)
        .map(|_| (0..DIM).map(|_| unit.sample(&mut rng)).collect())
        .collect();
    let drifts: Vec<Vec<f32>> = (0..50)
        .map(|_| (0..DIM).map(|_| 0.3 * unit.sample(&mut rng)).collect())
        .collect();
    turntable(n, |o, t| {
        (0..DIM)
            .map(|k| centres[o][k] + t * drifts[o][k] + 0.1 * unit.sample(&mut rng))
            .collect()
    })
}

/// `n` views in sequences of [`VIEWS`], cycling over 50 objects: `view(object, t)` with t the
/// position in the sequence, 0 ≤ t < 1. Labels are the objects.
fn turntable(n: usize, mut view: impl FnMut(usize, f32) -> Vec<f32>) -> Data {
    let mut d = Data {
        xs: Vec::with_capacity(n),
        sequence: Vec::with_capacity(n),
        label: Vec::with_capacity(n),
    };
    for i in 0..n {
        let seq = i / VIEWS;
        let o = (seq * 7919) % 50;
        d.xs.push(view(o, (i % VIEWS) as f32 / VIEWS as f32));
        d.sequence.push(seq as u64);
        d.label.push(o as u32);
    }
    d
}

/// GOOD-like views: 3 projections of 15 × 15 bins (D = 675), each a sum of 3 Gaussian blobs
/// normalised to sum 1; an object's blobs drift along its 20-view sequence. Non-negative,
/// smooth histograms, like the embedded default features.
fn histograms(n: usize, seed: u64) -> Data {
    const BINS: usize = 15;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Per object and projection: 3 blobs (centre x, centre y, spread, drift x, drift y).
    let objects: Vec<Vec<[f32; 5]>> = (0..50)
        .map(|_| {
            (0..9)
                .map(|_| {
                    [
                        rng.random::<f32>() * BINS as f32,
                        rng.random::<f32>() * BINS as f32,
                        1.0 + 2.0 * rng.random::<f32>(),
                        2.0 * rng.random::<f32>() - 1.0,
                        2.0 * rng.random::<f32>() - 1.0,
                    ]
                })
                .collect()
        })
        .collect();
    turntable(n, |o, t| {
        let mut x = vec![0.0f32; 3 * BINS * BINS];
        for (proj, out) in x.chunks_mut(BINS * BINS).enumerate() {
            for blob in &objects[o][3 * proj..3 * proj + 3] {
                let (cx, cy) = (blob[0] + t * blob[3], blob[1] + t * blob[4]);
                for (k, v) in out.iter_mut().enumerate() {
                    let (bx, by) = ((k % BINS) as f32 + 0.5, (k / BINS) as f32 + 0.5);
                    let r2 = (bx - cx).powi(2) + (by - cy).powi(2);
                    *v += (-0.5 * r2 / (blob[2] * blob[2])).exp();
                }
            }
            let total: f32 = out.iter().sum();
            out.iter_mut().for_each(|v| *v /= total);
        }
        x
    })
}

fn uniform(n: usize, seed: u64) -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Data {
        xs: (0..n)
            .map(|_| (0..DIM).map(|_| rng.random::<f32>()).collect())
            .collect(),
        sequence: (0..n).map(|i| (i / VIEWS) as u64).collect(),
        label: (0..n).map(|i| ((i / VIEWS) % 50) as u32).collect(),
    }
}

fn growth_config(nodes: usize) -> GdmConfig {
    let mut c = GdmConfig::paper_incremental();
    assert_eq!(c.metric, Metric::Manhattan);
    for m in [&mut c.episodic, &mut c.semantic] {
        m.activation_threshold = 0.999;
        m.habituation_threshold = 1.0;
        m.max_nodes = Some(nodes);
    }
    c
}

/// A dual model whose memories are grown to (at most) `nodes` nodes each.
fn grown_gdm(nodes: usize, data: &Data) -> Gdm {
    let mut gdm = Gdm::new(growth_config(nodes), data.xs[0].len()).unwrap();
    let samples = data.samples();
    for _ in 0..4 {
        gdm.train(&samples).unwrap();
        if gdm.episodic().len() >= nodes {
            break;
        }
    }
    gdm
}

fn grown_episodic(nodes: usize, data: &Data) -> GammaGwr {
    let params = growth_config(nodes).episodic;
    let mut net = GammaGwr::new(params, Metric::Manhattan, DIM, 2).unwrap();
    for _ in 0..4 {
        for (i, x) in data.xs.iter().enumerate() {
            if i % VIEWS == 0 {
                net.begin_sequence();
            }
            net.train_step(x, &[Some(data.label[i])], Supervision::Unsupervised)
                .unwrap();
        }
        if net.len() >= nodes {
            break;
        }
    }
    net
}

/// One intrinsic replay of the whole G-EM (RNATs of K + 1 = 3 nodes into both memories), on a
/// copy of `gdm` each time; throughput in replayed pseudo-samples.
fn bench_replay(group: &mut BenchmarkGroup<'_, WallTime>, name: &str, nodes: usize, gdm: &Gdm) {
    let stats = gdm.clone().replay().unwrap();
    group.throughput(Throughput::Elements(stats.samples as u64));
    group.sample_size(10);
    group.bench_function(BenchmarkId::new(name, nodes), |b| {
        b.iter_batched(
            || gdm.clone(),
            |mut g| black_box(g.replay().unwrap()),
            BatchSize::LargeInput,
        )
    });
    group.sample_size(20);
}

/// The positional filter criterion was given (`cargo bench -- FILTER`), if any.
fn filter() -> Option<String> {
    let mut args = std::env::args().skip(1);
    let mut found = None;
    while let Some(a) = args.next() {
        if a == "--bench" || a.starts_with("--") && a.contains('=') {
            continue;
        }
        if a.starts_with('-') {
            // Options with a value (`--save-baseline X`, ...): skip the value too, unless it
            // is a flag-only option criterion knows.
            if !matches!(
                a.as_str(),
                "--list" | "--quiet" | "--verbose" | "--noplot" | "--exact"
            ) {
                args.next();
            }
            continue;
        }
        found = Some(a);
    }
    found
}

/// False if a filter is given that matches none of the group's benchmark ids (so that the group
/// does not grow its networks for nothing).
fn wanted(ids: &[&str]) -> bool {
    filter().is_none_or(|f| ids.iter().any(|id| id.contains(f.as_str())))
}

/// Issue 42's cost check at the paper's size: 790 G-EM nodes, D = 256, K = 2, on clustered
/// data and on uniform data (the early-abandoning search's worst case).
fn bench_790(c: &mut Criterion) {
    const NODES: usize = 790;
    let mut group = c.benchmark_group("gdm_790");
    group
        .sample_size(30)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for (name, data) in [
        ("clustered", clustered(2 * NODES + 2200, 7)),
        ("uniform", uniform(2 * NODES + 2200, 8)),
    ] {
        let id = |what: &str| format!("{what}_{name}");
        let ids = [
            "train_step_episodic",
            "predict_per_200",
            "train_dual_per_200",
        ]
        .map(|w| format!("gdm_790/{}/{NODES}", id(w)));
        if !wanted(&ids.iter().map(String::as_str).collect::<Vec<_>>()) {
            continue;
        }
        let (grow, stream) = data.split(2 * NODES + 200);

        let mut net = grown_episodic(NODES, &grow);
        assert_eq!(
            net.len(),
            NODES,
            "the episodic network did not reach its cap"
        );
        let mut i = 0;
        group.throughput(Throughput::Elements(1));
        group.bench_function(BenchmarkId::new(id("train_step_episodic"), NODES), |b| {
            b.iter(|| {
                if i % VIEWS == 0 {
                    net.begin_sequence();
                }
                let k = i % stream.xs.len();
                let out = net
                    .train_step(
                        &stream.xs[k],
                        &[Some(stream.label[k])],
                        Supervision::Unsupervised,
                    )
                    .unwrap();
                i += 1;
                black_box(out)
            })
        });

        let mut gdm = grown_gdm(NODES, &grow);
        assert_eq!(
            gdm.episodic().len(),
            NODES,
            "the G-EM did not reach its cap"
        );
        eprintln!(
            "gdm_790 ({name}): {} episodic / {} semantic nodes",
            gdm.episodic().len(),
            gdm.semantic().len()
        );
        let samples = stream.samples();
        let batch = &samples[..200];
        group.throughput(Throughput::Elements(batch.len() as u64));
        group.bench_function(BenchmarkId::new(id("predict_per_200"), NODES), |b| {
            b.iter(|| black_box(gdm.predict(batch, PredictOptions::default()).unwrap()))
        });
        group.bench_function(BenchmarkId::new(id("train_dual_per_200"), NODES), |b| {
            b.iter(|| black_box(gdm.train(batch).unwrap()))
        });
    }
    group.finish();
}

fn bench(c: &mut Criterion) {
    if !wanted(&[
        "gdm/train_step_episodic/1000",
        "gdm/train_step_episodic/5000",
        "gdm/predict_clustered/1000",
        "gdm/predict_clustered/5000",
        "gdm/train_dual_clustered/1000",
        "gdm/train_dual_clustered/5000",
        "gdm/replay_clustered/1000",
        "gdm/replay_histograms/1000",
        "gdm/predict_uniform/5000",
    ]) {
        return;
    }
    let mut group = c.benchmark_group("gdm");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));

    for nodes in [1000usize, 5000] {
        // Growth data, then a stream of new views of the same objects.
        let data = clustered(2 * nodes + 2200, 1);
        let (grow, stream) = data.split(2 * nodes + 200);
        let (data, stream) = (&grow, &stream);

        // One memory: a training step on a capped episodic network.
        let mut net = grown_episodic(nodes, data);
        eprintln!(
            "episodic network: {} nodes, {} edges",
            net.len(),
            net.edge_count()
        );
        let mut i = 0;
        group.throughput(Throughput::Elements(1));
        group.bench_function(BenchmarkId::new("train_step_episodic", nodes), |b| {
            b.iter(|| {
                if i % VIEWS == 0 {
                    net.begin_sequence();
                }
                let x = &stream.xs[i % stream.xs.len()];
                let label = Some(stream.label[i % stream.xs.len()]);
                let out = net
                    .train_step(x, &[label], Supervision::Unsupervised)
                    .unwrap();
                i += 1;
                black_box(out)
            })
        });

        // Dual model: train (both memories) and predict, per sample.
        let mut gdm = grown_gdm(nodes, data);
        eprintln!(
            "dual model (clustered): {} episodic / {} semantic nodes, {:.1} MB",
            gdm.episodic().len(),
            gdm.semantic().len(),
            gdm.size_bytes() as f64 / 1e6
        );
        let samples = stream.samples();
        let batch = &samples[..200];
        group.throughput(Throughput::Elements(batch.len() as u64));
        group.bench_function(BenchmarkId::new("predict_clustered", nodes), |b| {
            b.iter(|| black_box(gdm.predict(batch, PredictOptions::default()).unwrap()))
        });
        group.bench_function(BenchmarkId::new("train_dual_clustered", nodes), |b| {
            b.iter(|| black_box(gdm.train(batch).unwrap()))
        });
        if nodes == 1000 {
            bench_replay(&mut group, "replay_clustered", nodes, &gdm);
        }
    }

    // Replay on GOOD-like histograms, where Manhattan's segment-sum bound prunes most nodes.
    let nodes = 1000;
    let gdm = grown_gdm(nodes, &histograms(2 * nodes + 200, 5));
    eprintln!(
        "dual model (histograms, D = 675): {} episodic / {} semantic nodes",
        gdm.episodic().len(),
        gdm.semantic().len()
    );
    bench_replay(&mut group, "replay_histograms", nodes, &gdm);

    let nodes = 5000;
    let data = uniform(2 * nodes + 200, 3);
    let gdm = grown_gdm(nodes, &data);
    eprintln!(
        "dual model (uniform): {} episodic / {} semantic nodes",
        gdm.episodic().len(),
        gdm.semantic().len()
    );
    let stream = uniform(200, 4);
    let samples = stream.samples();
    group.throughput(Throughput::Elements(samples.len() as u64));
    group.bench_function(BenchmarkId::new("predict_uniform", nodes), |b| {
        b.iter(|| black_box(gdm.predict(&samples, PredictOptions::default()).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, bench_790, bench);
criterion_main!(benches);
