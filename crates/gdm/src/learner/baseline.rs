//! The two baselines: streaming LDA (Hayes & Kanan, "Lifelong machine learning with deep
//! streaming linear discriminant analysis", 2020) and a nearest class mean, each with one head
//! per instance and one per category, learnt one sample at a time.
//!
//! A head keeps a running mean per label (count and mean, f64). Streaming LDA also keeps the
//! within-class scatter S, updated exactly (Welford) as each sample x of class c arrives:
//! S += n_c/(n_c+1) · (x − μ_c)(x − μ_c)ᵀ, then μ_c += (x − μ_c)/(n_c+1); the shared covariance
//! is Σ = S / N over the head's N samples — the batch pooled within-class covariance. It
//! predicts argmax_c W_c·x + b_c with Λ = (Σ + ε·I)⁻¹ (Cholesky, ε = [`SLDA_SHRINKAGE`]),
//! W_c = Λ μ_c, b_c = −½ μ_c·Λ μ_c. The nearest class mean predicts the label whose mean is
//! nearest by Euclidean distance. Ties go to the lowest label. A sample without an instance
//! (category) label does not teach the instance (category) head.
//!
//! The instance head's answer also gives a category — the category of the predicted instance
//! (the first category label seen with it) — as the GDM's episodic memory does: the "G-EM"
//! category figure. Training statistics: the "quantization error" of a head is the mean
//! Euclidean distance of each sample to the nearest mean before it is learnt.
//!
//! File format (integers little-endian): magic `LGDMBASE`, version (u32, 1), payload length
//! (u64), CRC-32 of the payload (u32); payload: learner (u8: 1 slda, 2 ncm), dim (u64), the
//! instance → category map (u64 count, then u32 instance + u32 category each), then the category
//! head and the instance head: label count (u64), per label u32 label + u64 count + dim f64
//! mean, the head's sample count (u64), and for slda the dim² f64 scatter (row-major).

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

use super::{Learner, LearnerKind};
use crate::dual::{check_dim, validate_batch};
use crate::scores::accuracy;
use crate::{CheckpointError, GdmError, PredictOptions, Prediction, Sample, Scores, TrainStats};

/// First bytes of a baseline's model file.
pub const MAGIC: [u8; 8] = *b"LGDMBASE";
/// Format version of the baseline model file.
pub const VERSION: u32 = 1;
const HEADER_LEN: usize = 8 + 4 + 8 + 4;
/// Shrinkage ε added to the covariance's diagonal before streaming LDA inverts it.
pub const SLDA_SHRINKAGE: f64 = 1e-4;
/// The largest input dimension streaming LDA takes (its covariance holds dim² numbers per head).
pub const MAX_SLDA_DIM: usize = 2048;

/// Running means per label, and for streaming LDA the within-class scatter.
#[derive(Clone, Debug, PartialEq)]
struct Head {
    /// Per label: sample count and mean.
    classes: BTreeMap<u32, (u64, Vec<f64>)>,
    /// Samples learnt.
    total: u64,
    /// Within-class scatter, dim × dim row-major (streaming LDA only).
    scatter: Option<Vec<f64>>,
}

impl Head {
    fn new(dim: usize, with_scatter: bool) -> Head {
        Head {
            classes: BTreeMap::new(),
            total: 0,
            scatter: with_scatter.then(|| vec![0.0; dim * dim]),
        }
    }

    /// Distance to the nearest mean, if any.
    fn nearest_distance(&self, x: &[f64]) -> Option<f64> {
        self.classes
            .values()
            .map(|(_, m)| squared_distance(x, m))
            .min_by(f64::total_cmp)
            .map(f64::sqrt)
    }

    fn learn(&mut self, x: &[f64], label: u32) {
        let dim = x.len();
        let (n, mean) = self
            .classes
            .entry(label)
            .or_insert_with(|| (0, vec![0.0; dim]));
        let nf = *n as f64;
        let d: Vec<f64> = x.iter().zip(mean.iter()).map(|(a, b)| a - b).collect();
        if let Some(s) = &mut self.scatter {
            let w = nf / (nf + 1.0);
            if w > 0.0 {
                for i in 0..dim {
                    let wi = w * d[i];
                    let row = &mut s[i * dim..(i + 1) * dim];
                    for (sj, dj) in row.iter_mut().zip(&d) {
                        *sj += wi * dj;
                    }
                }
            }
        }
        for (m, di) in mean.iter_mut().zip(&d) {
            *m += di / (nf + 1.0);
        }
        *n += 1;
        self.total += 1;
    }

    /// The shared covariance S / N (zero before any sample).
    fn covariance(&self, dim: usize) -> Option<DMatrix<f64>> {
        let s = self.scatter.as_ref()?;
        let n = self.total.max(1) as f64;
        Some(DMatrix::from_row_slice(dim, dim, s).map(|v| v / n))
    }

    /// What prediction needs, computed once per batch.
    fn scorer(&self, dim: usize) -> Result<Option<Scorer<'_>>, GdmError> {
        if self.classes.is_empty() {
            return Ok(None);
        }
        let labels: Vec<u32> = self.classes.keys().copied().collect();
        let linear = match self.covariance(dim) {
            None => None,
            Some(mut sigma) => {
                for i in 0..dim {
                    sigma[(i, i)] += SLDA_SHRINKAGE;
                }
                let chol = sigma.cholesky().ok_or_else(|| {
                    GdmError::Learner(format!(
                        "streaming LDA: the covariance plus {SLDA_SHRINKAGE}·I is not positive \
                         definite (features too large or degenerate)"
                    ))
                })?;
                let mut w = Vec::with_capacity(labels.len());
                let mut b = Vec::with_capacity(labels.len());
                for (_, mean) in self.classes.values() {
                    let mu = DVector::from_column_slice(mean);
                    let wc = chol.solve(&mu);
                    b.push(-0.5 * mu.dot(&wc));
                    w.push(wc.as_slice().to_vec());
                }
                Some((w, b))
            }
        };
        Ok(Some(Scorer {
            head: self,
            labels,
            linear,
        }))
    }
}

/// A head ready to predict.
struct Scorer<'a> {
    head: &'a Head,
    labels: Vec<u32>,
    /// Streaming LDA: W_c and b_c per label, in label order.
    linear: Option<(Vec<Vec<f64>>, Vec<f64>)>,
}

impl Scorer<'_> {
    /// The predicted label and the distance to its mean.
    fn predict(&self, x: &[f64]) -> (u32, f64) {
        let means = self.head.classes.values().map(|(_, m)| m);
        let best = match &self.linear {
            Some((w, b)) => {
                let scores = w.iter().zip(b).map(|(wc, bc)| dot(wc, x) + bc);
                argbest(scores, |a, b| a > b)
            }
            None => argbest(means.map(|m| squared_distance(x, m)), |a, b| a < b),
        };
        let mean = &self.head.classes[&self.labels[best]].1;
        (self.labels[best], squared_distance(x, mean).sqrt())
    }
}

/// Index of the best value (`better(a, b)`: a beats b); the first of equals.
fn argbest(values: impl Iterator<Item = f64>, better: impl Fn(f64, f64) -> bool) -> usize {
    let mut best: Option<(usize, f64)> = None;
    for (i, v) in values.enumerate() {
        if best.is_none_or(|(_, b)| better(v, b)) {
            best = Some((i, v));
        }
    }
    best.map_or(0, |(i, _)| i)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn squared_distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn widen(x: &[f32]) -> Vec<f64> {
    x.iter().map(|&v| f64::from(v)).collect()
}

/// A baseline learner: streaming LDA or nearest class mean (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Baseline {
    kind: LearnerKind,
    dim: usize,
    category: Head,
    instance: Head,
    /// The category of each instance (the first seen with it).
    instance_category: BTreeMap<u32, u32>,
}

impl Baseline {
    /// An untrained baseline of `kind` (slda or ncm) for `dim`-dimensional features.
    pub fn new(kind: LearnerKind, dim: usize) -> Result<Baseline, GdmError> {
        check_dim(dim)?;
        if kind == LearnerKind::Gdm {
            return Err(GdmError::Learner(
                "the gdm learner is the dual memory, not a baseline".into(),
            ));
        }
        let slda = kind == LearnerKind::Slda;
        if slda && dim > MAX_SLDA_DIM {
            return Err(GdmError::DimensionTooLarge {
                dim,
                max: MAX_SLDA_DIM,
            });
        }
        Ok(Baseline {
            kind,
            dim,
            category: Head::new(dim, slda),
            instance: Head::new(dim, slda),
            instance_category: BTreeMap::new(),
        })
    }

    /// The running mean and sample count of category `c`, if learnt.
    pub fn category_mean(&self, c: u32) -> Option<(u64, &[f64])> {
        self.category.classes.get(&c).map(|(n, m)| (*n, &m[..]))
    }

    /// The running mean and sample count of instance `i`, if learnt.
    pub fn instance_mean(&self, i: u32) -> Option<(u64, &[f64])> {
        self.instance.classes.get(&i).map(|(n, m)| (*n, &m[..]))
    }

    /// Streaming LDA: the shared covariance of the category head (row-major dim × dim).
    pub fn category_covariance(&self) -> Option<Vec<f64>> {
        self.category
            .covariance(self.dim)
            .map(|m| m.transpose().as_slice().to_vec())
    }

    fn details(&self, samples: &[Sample<'_>]) -> Result<Vec<(Prediction, f64, f64)>, GdmError> {
        validate_batch(samples, self.dim)?;
        let inst = self.instance.scorer(self.dim)?;
        let cat = self.category.scorer(self.dim)?;
        if inst.is_none() && cat.is_none() {
            return Err(GdmError::NotTrained);
        }
        Ok(samples
            .iter()
            .map(|s| {
                let x = widen(s.x);
                let i = inst.as_ref().map(|h| h.predict(&x));
                let c = cat.as_ref().map(|h| h.predict(&x));
                let d_em = i.map_or(f64::NAN, |(_, d)| d);
                let prediction = Prediction {
                    instance: i.map(|(l, _)| l),
                    category_em: i.and_then(|(l, _)| self.instance_category.get(&l).copied()),
                    category: c.map(|(l, _)| l),
                    activation: (-d_em).exp() as f32,
                };
                (prediction, d_em, c.map_or(f64::NAN, |(_, d)| d))
            })
            .collect())
    }

    /// The model file's bytes (see the module docs).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut p = Vec::new();
        p.push(match self.kind {
            LearnerKind::Slda => 1u8,
            _ => 2u8,
        });
        p.extend_from_slice(&(self.dim as u64).to_le_bytes());
        p.extend_from_slice(&(self.instance_category.len() as u64).to_le_bytes());
        for (i, c) in &self.instance_category {
            p.extend_from_slice(&i.to_le_bytes());
            p.extend_from_slice(&c.to_le_bytes());
        }
        for head in [&self.category, &self.instance] {
            p.extend_from_slice(&(head.classes.len() as u64).to_le_bytes());
            for (label, (n, mean)) in &head.classes {
                p.extend_from_slice(&label.to_le_bytes());
                p.extend_from_slice(&n.to_le_bytes());
                mean.iter()
                    .for_each(|v| p.extend_from_slice(&v.to_le_bytes()));
            }
            p.extend_from_slice(&head.total.to_le_bytes());
            if let Some(s) = &head.scatter {
                s.iter().for_each(|v| p.extend_from_slice(&v.to_le_bytes()));
            }
        }
        let mut out = Vec::with_capacity(HEADER_LEN + p.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(p.len() as u64).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&p).to_le_bytes());
        out.extend_from_slice(&p);
        out
    }

    /// Reads a baseline's model file; every kind of damage gives a typed error, and a GDM
    /// checkpoint is refused naming its learner.
    pub fn from_bytes(bytes: &[u8]) -> Result<Baseline, CheckpointError> {
        if bytes.starts_with(&crate::checkpoint::MAGIC) {
            return Err(CheckpointError::OtherLearner {
                found: "gdm".into(),
                expected: "slda or ncm".into(),
            });
        }
        let header = check_header(bytes)?;
        let mut r = Reader {
            buf: &bytes[header..],
            pos: 0,
        };
        let kind = match r.take(1)?[0] {
            1 => LearnerKind::Slda,
            2 => LearnerKind::Ncm,
            other => return Err(corrupt(format!("unknown learner code {other}"))),
        };
        let dim = r.u64()?;
        let max = if kind == LearnerKind::Slda {
            MAX_SLDA_DIM
        } else {
            crate::config::MAX_DIM
        };
        if dim == 0 || dim > max as u64 {
            return Err(corrupt(format!("dimension {dim} is not in 1..={max}")));
        }
        let dim = dim as usize;
        if kind == LearnerKind::Slda {
            // Both heads' scatters must be there before they are allocated.
            r.count_raw(2 * (dim * dim) as u64, 8)?;
        }
        let mut model = Baseline::new(kind, dim).map_err(|e| corrupt(e.to_string()))?;
        let pairs = r.count(8)?;
        for _ in 0..pairs {
            let i = r.u32()?;
            let c = r.u32()?;
            if model
                .instance_category
                .last_key_value()
                .is_some_and(|(&p, _)| p >= i)
            {
                return Err(corrupt(format!("instance {i} out of ascending order")));
            }
            model.instance_category.insert(i, c);
        }
        for (name, head) in [
            ("category", &mut model.category),
            ("instance", &mut model.instance),
        ] {
            let labels = r.count(12 + 8 * dim)?;
            let mut sum = 0u64;
            for _ in 0..labels {
                let label = r.u32()?;
                let n = r.u64()?;
                let mean = r.f64s(dim)?;
                if n == 0 {
                    return Err(corrupt(format!("{name} {label}: a mean of no sample")));
                }
                if head
                    .classes
                    .last_key_value()
                    .is_some_and(|(&p, _)| p >= label)
                {
                    return Err(corrupt(format!("{name} {label} out of ascending order")));
                }
                sum = sum.saturating_add(n);
                head.classes.insert(label, (n, mean));
            }
            head.total = r.u64()?;
            if head.total != sum {
                return Err(corrupt(format!(
                    "{name} head: {} samples, its means count {sum}",
                    head.total
                )));
            }
            if head.scatter.is_some() {
                r.count_raw((dim * dim) as u64, 8)?;
                head.scatter = Some(r.f64s(dim * dim)?);
            }
        }
        if r.pos != r.buf.len() {
            return Err(corrupt(format!(
                "{} unread bytes at the end of the payload",
                r.buf.len() - r.pos
            )));
        }
        Ok(model)
    }
}

fn corrupt(m: String) -> CheckpointError {
    CheckpointError::Corrupt(m)
}

/// Checks magic, version, length and checksum; the payload's offset.
fn check_header(bytes: &[u8]) -> Result<usize, CheckpointError> {
    let n = bytes.len().min(MAGIC.len());
    if bytes[..n] != MAGIC[..n] {
        return Err(CheckpointError::BadMagic);
    }
    if bytes.len() < HEADER_LEN {
        return Err(CheckpointError::Truncated {
            expected: HEADER_LEN as u64,
            found: bytes.len() as u64,
        });
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(CheckpointError::Version {
            found: version,
            supported: VERSION,
        });
    }
    let len = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
    let crc = u32::from_le_bytes(bytes[20..24].try_into().expect("4 bytes"));
    let expected = (HEADER_LEN as u64).saturating_add(len);
    if (bytes.len() as u64) < expected {
        return Err(CheckpointError::Truncated {
            expected,
            found: bytes.len() as u64,
        });
    }
    if (bytes.len() as u64) > expected {
        return Err(corrupt(format!(
            "{} bytes after the declared payload",
            bytes.len() as u64 - expected
        )));
    }
    let found = crc32fast::hash(&bytes[HEADER_LEN..]);
    if found != crc {
        return Err(CheckpointError::Checksum {
            expected: crc,
            found,
        });
    }
    Ok(HEADER_LEN)
}

struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CheckpointError> {
        if self.buf.len() - self.pos < n {
            return Err(corrupt(format!(
                "payload ends at byte {}, {n} more expected",
                self.buf.len()
            )));
        }
        let out = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }
    fn u32(&mut self) -> Result<u32, CheckpointError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }
    fn u64(&mut self) -> Result<u64, CheckpointError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8")))
    }
    /// Checks that `n` items of `each` bytes fit in what is left.
    fn count_raw(&self, n: u64, each: usize) -> Result<usize, CheckpointError> {
        let left = (self.buf.len() - self.pos) as u64;
        match n.checked_mul(each as u64) {
            Some(bytes) if bytes <= left => Ok(n as usize),
            _ => Err(corrupt(format!(
                "{n} items of {each} bytes declared, {left} bytes left"
            ))),
        }
    }
    /// A count (u64) of items of `each` bytes, checked against what is left.
    fn count(&mut self, each: usize) -> Result<usize, CheckpointError> {
        let n = self.u64()?;
        self.count_raw(n, each)
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, CheckpointError> {
        self.count_raw(n as u64, 8)?;
        let bytes = self.take(n * 8)?;
        let out: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8")))
            .collect();
        if out.iter().any(|v| !v.is_finite()) {
            return Err(corrupt("a non-finite number".into()));
        }
        Ok(out)
    }
}

impl Learner for Baseline {
    fn kind(&self) -> LearnerKind {
        self.kind
    }

    fn dim(&self) -> usize {
        self.dim
    }

    fn learn(&mut self, samples: &[Sample<'_>]) -> Result<TrainStats, GdmError> {
        validate_batch(samples, self.dim)?;
        let (mut qe_em, mut n_em, mut qe_sm, mut n_sm) = (0.0f64, 0usize, 0.0f64, 0usize);
        for s in samples {
            let x = widen(s.x);
            if let Some(i) = s.instance {
                if let Some(d) = self.instance.nearest_distance(&x) {
                    qe_em += d;
                    n_em += 1;
                }
                self.instance.learn(&x, i);
                if let Some(c) = s.category {
                    self.instance_category.entry(i).or_insert(c);
                }
            }
            if let Some(c) = s.category {
                if let Some(d) = self.category.nearest_distance(&x) {
                    qe_sm += d;
                    n_sm += 1;
                }
                self.category.learn(&x, c);
            }
        }
        let mean = |q: f64, n: usize| if n > 0 { q / n as f64 } else { 0.0 };
        Ok(TrainStats {
            samples: samples.len(),
            episodic_nodes: self.instance.classes.len(),
            semantic_nodes: self.category.classes.len(),
            quantization_error_em: mean(qe_em, n_em),
            quantization_error_sm: mean(qe_sm, n_sm),
        })
    }

    fn end_step(&mut self, replay: bool) -> Result<(), GdmError> {
        if replay {
            return Err(GdmError::Learner(format!(
                "the {} learner has no replay (replay is the gdm learner's)",
                self.kind
            )));
        }
        Ok(())
    }

    fn predict(
        &self,
        samples: &[Sample<'_>],
        _opts: PredictOptions,
    ) -> Result<Vec<Prediction>, GdmError> {
        Ok(self.details(samples)?.into_iter().map(|d| d.0).collect())
    }

    fn evaluate(&self, samples: &[Sample<'_>], opts: PredictOptions) -> Result<Scores, GdmError> {
        Ok(self.evaluate_with_predictions(samples, opts)?.0)
    }

    fn evaluate_with_predictions(
        &self,
        samples: &[Sample<'_>],
        _opts: PredictOptions,
    ) -> Result<(Scores, Vec<Prediction>), GdmError> {
        let details = self.details(samples)?;
        let n = details.len();
        let pairs = |f: fn(&Prediction) -> Option<u32>, g: fn(&Sample<'_>) -> Option<u32>| {
            accuracy(details.iter().zip(samples).map(|(d, s)| (f(&d.0), g(s))))
        };
        let scores = Scores {
            n,
            instance_accuracy: pairs(|p| p.instance, |s| s.instance),
            category_accuracy_em: pairs(|p| p.category_em, |s| s.category),
            category_accuracy_sm: pairs(|p| p.category, |s| s.category),
            quantization_error_em: details.iter().map(|d| d.1).sum::<f64>() / n as f64,
            quantization_error_sm: details.iter().map(|d| d.2).sum::<f64>() / n as f64,
        };
        Ok((scores, details.into_iter().map(|d| d.0).collect()))
    }

    fn nodes(&self) -> (usize, usize) {
        (self.instance.classes.len(), self.category.classes.len())
    }

    fn to_bytes(&self) -> Vec<u8> {
        Baseline::to_bytes(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A stream of `n` samples of two 3-d Gaussians (category = instance = which one), the
    /// categories interleaved; a correlated covariance so LDA's and NCM's answers can differ.
    fn two_gaussians(n: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0f64, 1.0).expect("valid");
        let mut xs = Vec::new();
        let mut labels = Vec::new();
        for k in 0..n {
            let c = (k % 2) as u32;
            let (a, b, e) = (
                normal.sample(&mut rng),
                normal.sample(&mut rng),
                normal.sample(&mut rng),
            );
            let shift = if c == 0 { -2.0 } else { 2.0 };
            // Correlated noise, large along (1, 1, 0), small along (1, −1, 0); the means differ
            // along x, so the nearest mean (blind to the covariance) confuses them often.
            let x = [3.0 * a + 0.3 * b + shift, 3.0 * a - 0.3 * b, e];
            xs.push(x.map(|v| v as f32));
            labels.push(c);
        }
        (xs, labels)
    }

    fn samples<'a>(xs: &'a [[f32; 3]], labels: &[u32]) -> Vec<Sample<'a>> {
        xs.iter()
            .zip(labels)
            .enumerate()
            .map(|(k, (x, &c))| Sample::labelled(x, k as u64, c, c))
            .collect()
    }

    #[test]
    fn slda_separates_two_correlated_gaussians() {
        let (xs, labels) = two_gaussians(2000, 1);
        let (test_x, test_labels) = two_gaussians(1000, 2);
        let mut slda = Baseline::new(LearnerKind::Slda, 3).unwrap();
        slda.learn(&samples(&xs, &labels)).unwrap();
        let test = samples(&test_x, &test_labels);
        let scores = slda.evaluate(&test, PredictOptions::default()).unwrap();
        // Bayes accuracy is ≈ 0.9996 (the means are 6.7 standard deviations apart along the
        // discriminating direction); NCM, on x alone, about 0.75.
        assert!(scores.category_accuracy_sm > 0.99, "{scores:?}");
        assert!(scores.instance_accuracy > 0.99, "{scores:?}");
        assert!(scores.category_accuracy_em > 0.99, "{scores:?}");
        let mut ncm = Baseline::new(LearnerKind::Ncm, 3).unwrap();
        ncm.learn(&samples(&xs, &labels)).unwrap();
        let ncm_scores = ncm.evaluate(&test, PredictOptions::default()).unwrap();
        assert!(ncm_scores.category_accuracy_sm < 0.9, "{ncm_scores:?}");
    }

    #[test]
    fn ncm_means_equal_the_batch_class_means() {
        let (xs, labels) = two_gaussians(501, 3);
        let mut ncm = Baseline::new(LearnerKind::Ncm, 3).unwrap();
        // In three calls: a stream continues across calls.
        let all = samples(&xs, &labels);
        for chunk in all.chunks(200) {
            ncm.learn(chunk).unwrap();
        }
        for c in 0..2u32 {
            let rows: Vec<&[f32; 3]> = xs
                .iter()
                .zip(&labels)
                .filter(|(_, l)| **l == c)
                .map(|(x, _)| x)
                .collect();
            let (n, mean) = ncm.category_mean(c).unwrap();
            assert_eq!(n as usize, rows.len());
            for (j, m) in mean.iter().enumerate() {
                let batch = rows.iter().map(|x| f64::from(x[j])).sum::<f64>() / rows.len() as f64;
                assert!(
                    (m - batch).abs() < 1e-12,
                    "class {c} dim {j}: {m} vs {batch}"
                );
            }
            assert_eq!(ncm.instance_mean(c).unwrap().1, mean);
        }
        // The nearest mean wins: a point at a class mean is that class.
        let at = ncm
            .category_mean(1)
            .unwrap()
            .1
            .iter()
            .map(|&v| v as f32)
            .collect::<Vec<_>>();
        let p = ncm
            .predict(&[Sample::unlabelled(&at, 0)], PredictOptions::default())
            .unwrap();
        assert_eq!(p[0].category, Some(1));
    }

    #[test]
    fn streaming_covariance_equals_the_batch_covariance() {
        let (xs, labels) = two_gaussians(777, 4);
        let mut slda = Baseline::new(LearnerKind::Slda, 3).unwrap();
        for s in samples(&xs, &labels) {
            slda.learn(&[s]).unwrap();
        }
        let mut means = [[0.0f64; 3]; 2];
        let mut counts = [0usize; 2];
        for (x, &c) in xs.iter().zip(&labels) {
            counts[c as usize] += 1;
            for j in 0..3 {
                means[c as usize][j] += f64::from(x[j]);
            }
        }
        for c in 0..2 {
            means[c] = means[c].map(|v| v / counts[c] as f64);
        }
        let mut batch = [[0.0f64; 3]; 3];
        for (x, &c) in xs.iter().zip(&labels) {
            let d: Vec<f64> = (0..3)
                .map(|j| f64::from(x[j]) - means[c as usize][j])
                .collect();
            for i in 0..3 {
                for j in 0..3 {
                    batch[i][j] += d[i] * d[j] / xs.len() as f64;
                }
            }
        }
        let cov = slda.category_covariance().unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (cov[i * 3 + j] - batch[i][j]).abs() < 1e-9,
                    "({i},{j}): {} vs {}",
                    cov[i * 3 + j],
                    batch[i][j]
                );
            }
        }
        assert!(batch[0][0] > 1.0, "a real covariance, not zeros");
    }

    #[test]
    fn model_files_round_trip_and_refuse_damage_and_other_learners() {
        let (xs, labels) = two_gaussians(50, 5);
        for kind in [LearnerKind::Slda, LearnerKind::Ncm] {
            let mut b = Baseline::new(kind, 3).unwrap();
            b.learn(&samples(&xs, &labels)).unwrap();
            let bytes = b.to_bytes();
            assert_eq!(Baseline::from_bytes(&bytes).unwrap(), b);
            for cut in [0, 5, HEADER_LEN, bytes.len() - 1] {
                assert!(Baseline::from_bytes(&bytes[..cut]).is_err(), "cut at {cut}");
            }
            let mut flipped = bytes.clone();
            flipped[HEADER_LEN + 3] ^= 1;
            assert!(matches!(
                Baseline::from_bytes(&flipped),
                Err(CheckpointError::Checksum { .. })
            ));
            let err = crate::Gdm::from_bytes(&bytes).unwrap_err();
            assert!(
                err.to_string().contains(&format!("the {kind} learner")),
                "{err}"
            );
            let model = super::super::Model::from_bytes(&bytes).unwrap();
            assert_eq!(model.kind(), kind);
        }
        let gdm = crate::Gdm::new(crate::GdmConfig::default(), 3).unwrap();
        let err = Baseline::from_bytes(&gdm.to_bytes()).unwrap_err();
        assert!(err.to_string().contains("gdm learner"), "{err}");
    }

    #[test]
    fn baselines_refuse_replay_and_an_untrained_prediction() {
        let mut b = Baseline::new(LearnerKind::Ncm, 2).unwrap();
        let err = b.end_step(true).unwrap_err();
        assert!(
            err.to_string().contains("ncm learner has no replay"),
            "{err}"
        );
        assert!(matches!(
            b.predict(
                &[Sample::unlabelled(&[0.0, 0.0], 0)],
                PredictOptions::default()
            ),
            Err(GdmError::NotTrained)
        ));
        assert!(matches!(
            Baseline::new(LearnerKind::Slda, MAX_SLDA_DIM + 1),
            Err(GdmError::DimensionTooLarge { .. })
        ));
    }
}
