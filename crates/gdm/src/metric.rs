//! Distance metrics between feature vectors, and the best-matching-node search that uses them.
//!
//! The search is the hot loop of the whole crate: it scans the contiguous node buffer of a
//! [`GammaGwr`](crate::GammaGwr), accumulates in 8 lanes so that the compiler vectorises it,
//! allocates nothing (for D·(K+1) up to about 8k), and abandons a node as soon as a lower bound
//! of its distance exceeds the current second-best (training) or best (prediction) distance.
//! For Manhattan, each node also keeps a summary (the sums of every 16 inputs of each block, and
//! the block's L1 norm): Σ|Σq − Σw| over segments bounds the distance from below, so most nodes
//! are skipped after reading 3 × 44 floats instead of their first 64 (D = 675, K = 2). Nodes the
//! caller expects near the match (the previous best, replay's source node) are tried first, so
//! the bound is tight from the start. All of this is exact, rounding included: it never changes
//! which nodes are found, only the work.
//!
//! The build targets baseline x86-64 (SSE2), where each 8-lane step is two 4-float adds. On a
//! CPU with AVX2 (detected at run time) the kernels and the search loop run as a second copy of
//! the same source compiled with AVX2 enabled, one 8-float add per step: the same operations in
//! the same order (8 independent lanes, one left-to-right reduction, no FMA), so the results are
//! bit-identical on every CPU and only the speed differs.
//!
//! ```
//! use lgdm_gdm::metric::{self, Metric};
//! let a = [1.0, 2.0, 3.0];
//! let b = [2.0, 0.0, 3.0];
//! assert_eq!(metric::manhattan(&a, &b), 3.0);
//! assert_eq!(Metric::SquaredEuclidean.distance(&a, &b), 5.0);
//! ```

use serde::{Deserialize, Serialize};

use crate::error::ConfigError;

/// Distance between an input (or context) vector and a node's vector.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Metric {
    /// Σ|a − b| (default; the paper's choice).
    #[default]
    Manhattan,
    /// √Σ(a − b)².
    Euclidean,
    /// Σ(a − b)².
    SquaredEuclidean,
    /// (Σ|a − b|^p)^(1/p), p ≥ 1.
    Minkowski {
        /// The power p ≥ 1.
        p: f32,
    },
    /// 1 − a·b / (|a| |b|); 0 between two zero vectors, 1 between a zero and a non-zero vector.
    Cosine,
    /// Diagonal Mahalanobis distance √Σ(a − b)²/σ², with the per-feature variance σ² a running
    /// estimate over each memory's training inputs (plus 1e-6; unit variance before the second
    /// input). A full covariance would cost D² per node and is not offered.
    Mahalanobis,
}

impl Metric {
    /// Checks the metric's parameters (Minkowski needs a finite p ≥ 1).
    pub fn validate(&self) -> Result<(), ConfigError> {
        match *self {
            Metric::Minkowski { p } if !(p.is_finite() && p >= 1.0) => Err(ConfigError::invalid(
                "metric.p",
                format!("Minkowski power {p} must be finite and ≥ 1"),
            )),
            _ => Ok(()),
        }
    }

    /// Distance between `a` and `b` (equal lengths). Mahalanobis here uses unit variance, i.e.
    /// equals Euclidean; see [`mahalanobis_diagonal`] for explicit variances.
    pub fn distance(&self, a: &[f32], b: &[f32]) -> f32 {
        match *self {
            Metric::Manhattan => manhattan(a, b),
            Metric::Euclidean | Metric::Mahalanobis => euclidean(a, b),
            Metric::SquaredEuclidean => squared_euclidean(a, b),
            Metric::Minkowski { p } => minkowski(a, b, p),
            Metric::Cosine => cosine(a, b),
        }
    }
}

const LANES: usize = 8;

/// Which compiled copy of the kernels runs: the portable one (the build's baseline target), or
/// on x86-64 CPUs with AVX2 the same source compiled with AVX2 enabled. Both give bit-identical
/// results (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kernels {
    /// The build's baseline instruction set.
    Portable,
    /// AVX2; only ever made by [`Kernels::detect`] on a CPU that has it.
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Kernels {
    /// The fastest copy this CPU runs (the detection is cached by the standard library).
    #[inline(always)]
    pub(crate) fn detect() -> Kernels {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Kernels::Avx2;
        }
        Kernels::Portable
    }
}

/// Calls `$name(args)` in the copy `$kernels` selects: the function itself, or its namesake in
/// [`avx2`].
macro_rules! dispatch {
    ($kernels:expr, $name:ident($($arg:expr),* $(,)?)) => {
        match $kernels {
            Kernels::Portable => $name($($arg),*),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Kernels::Avx2` is only made by `Kernels::detect`, after the run-time
            // check that this CPU has AVX2.
            #[allow(unsafe_code)]
            Kernels::Avx2 => unsafe { avx2::$name($($arg),*) },
        }
    };
}

/// The kernels and the search compiled with AVX2 enabled: each is a wrapper around the portable
/// function (all `#[inline(always)]`), so its body is the same source, vectorised with 8-float
/// registers. Callers must have checked that the CPU has AVX2 ([`Kernels::detect`]).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Accumulator, Matches, NodeBuffer};

    #[target_feature(enable = "avx2")]
    pub(super) fn sum_l1(a: &[f32], b: &[f32]) -> f32 {
        super::sum_l1(a, b)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn sum_sq(a: &[f32], b: &[f32]) -> f32 {
        super::sum_sq(a, b)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn sum_sq_w(a: &[f32], b: &[f32], w: &[f32]) -> f32 {
        super::sum_sq_w(a, b, w)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn dot_norms(a: &[f32], b: &[f32]) -> (f32, f32, f32) {
        super::dot_norms(a, b)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn search_monotone<A: Accumulator>(
        acc: &A,
        buf: &NodeBuffer<'_>,
        query: &[f32],
        alphas: &[f32],
        want_second: bool,
        seeds: &[usize],
        query_summary: Option<&[f32]>,
    ) -> Option<Matches> {
        super::search_monotone(acc, buf, query, alphas, want_second, seeds, query_summary)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn search_cosine(
        buf: &NodeBuffer<'_>,
        query: &[f32],
        alphas: &[f32],
        want_second: bool,
    ) -> Option<Matches> {
        super::search_cosine(buf, query, alphas, want_second)
    }
}

/// Σ|a − b|.
pub fn manhattan(a: &[f32], b: &[f32]) -> f32 {
    dispatch!(Kernels::detect(), sum_l1(a, b))
}

/// √Σ(a − b)².
pub fn euclidean(a: &[f32], b: &[f32]) -> f32 {
    dispatch!(Kernels::detect(), sum_sq(a, b)).sqrt()
}

/// Σ(a − b)².
pub fn squared_euclidean(a: &[f32], b: &[f32]) -> f32 {
    dispatch!(Kernels::detect(), sum_sq(a, b))
}

/// (Σ|a − b|^p)^(1/p).
pub fn minkowski(a: &[f32], b: &[f32], p: f32) -> f32 {
    sum_lp(a, b, p).powf(1.0 / p)
}

/// 1 − a·b / (|a| |b|); 0 if both are zero vectors, 1 if exactly one is.
pub fn cosine(a: &[f32], b: &[f32]) -> f32 {
    let (dot, na, nb) = dispatch!(Kernels::detect(), dot_norms(a, b));
    cosine_from(dot, na, nb)
}

/// √Σ(a − b)² · inv_var, with `inv_var` the per-feature inverse variances.
pub fn mahalanobis_diagonal(a: &[f32], b: &[f32], inv_var: &[f32]) -> f32 {
    dispatch!(Kernels::detect(), sum_sq_w(a, b, inv_var)).sqrt()
}

#[inline(always)]
fn cosine_from(dot: f32, na: f32, nb: f32) -> f32 {
    if na == 0.0 && nb == 0.0 {
        0.0
    } else if na == 0.0 || nb == 0.0 {
        1.0
    } else {
        (1.0 - dot / (na.sqrt() * nb.sqrt())).max(0.0)
    }
}

#[inline(always)]
fn reduce(acc: [f32; LANES]) -> f32 {
    // A plain left-to-right sum: deterministic, and (unlike a pairwise tree) it lets LLVM keep
    // the lane accumulators in full-width SSE registers.
    acc.iter().sum()
}

#[inline(always)]
fn sum_l1(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..LANES {
            acc[i] += (x[i] - y[i]).abs();
        }
    }
    let mut s = reduce(acc);
    for (x, y) in ra.iter().zip(rb) {
        s += (x - y).abs();
    }
    s
}

#[inline(always)]
fn sum_sq(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..LANES {
            let d = x[i] - y[i];
            acc[i] += d * d;
        }
    }
    let mut s = reduce(acc);
    for (x, y) in ra.iter().zip(rb) {
        s += (x - y) * (x - y);
    }
    s
}

#[inline(always)]
fn sum_sq_w(a: &[f32], b: &[f32], w: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let cw = w.chunks_exact(LANES);
    let (ra, rb, rw) = (ca.remainder(), cb.remainder(), cw.remainder());
    for ((x, y), z) in ca.zip(cb).zip(cw) {
        for i in 0..LANES {
            let d = x[i] - y[i];
            acc[i] += d * d * z[i];
        }
    }
    let mut s = reduce(acc);
    for ((x, y), z) in ra.iter().zip(rb).zip(rw) {
        s += (x - y) * (x - y) * z;
    }
    s
}

#[inline(always)]
fn sum_lp(a: &[f32], b: &[f32], p: f32) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs().powf(p)).sum()
}

#[inline(always)]
fn dot_norms(a: &[f32], b: &[f32]) -> (f32, f32, f32) {
    let mut d = [0.0f32; LANES];
    let mut na = [0.0f32; LANES];
    let mut nb = [0.0f32; LANES];
    let ca = a.chunks_exact(LANES);
    let cb = b.chunks_exact(LANES);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..LANES {
            d[i] += x[i] * y[i];
            na[i] += x[i] * x[i];
            nb[i] += y[i] * y[i];
        }
    }
    let (mut sd, mut sa, mut sb) = (reduce(d), reduce(na), reduce(nb));
    for (x, y) in ra.iter().zip(rb) {
        sd += x * y;
        sa += x * x;
        sb += y * y;
    }
    (sd, sa, sb)
}

/// Result of a best-matching-node search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Matches {
    /// Best node and its distance.
    pub best: (usize, f32),
    /// Second-best node and its distance, if searched for and there are ≥ 2 nodes.
    pub second: Option<(usize, f32)>,
}

/// Where to search: the node buffer of a network and the layout of its blocks.
pub(crate) struct NodeBuffer<'a> {
    /// n × depth × dim floats.
    pub weights: &'a [f32],
    /// n × [`prefix_len`]`(dim)` floats: the first input-weight floats of every node, contiguous
    /// (a copy of `weights`), so that the first early-abandon check streams through memory.
    pub prefix: &'a [f32],
    /// n × [`summary_len`]`(dim, depth)` floats: every node's [`summarise`] (Manhattan's lower
    /// bound), contiguous.
    pub summary: &'a [f32],
    /// Input dimension D.
    pub dim: usize,
    /// Blocks per node (K + 1).
    pub depth: usize,
}

/// A monotone per-element accumulator: the distance of one block is `finish(Σ accumulate)`, and
/// `finish` is non-decreasing, so partial sums give lower bounds.
trait Accumulator {
    fn accumulate(&self, a: &[f32], b: &[f32], offset: usize) -> f32;
    fn finish(&self, s: f32) -> f32;
}

struct L1;
impl Accumulator for L1 {
    #[inline(always)]
    fn accumulate(&self, a: &[f32], b: &[f32], _: usize) -> f32 {
        sum_l1(a, b)
    }
    #[inline(always)]
    fn finish(&self, s: f32) -> f32 {
        s
    }
}

struct L2;
impl Accumulator for L2 {
    #[inline(always)]
    fn accumulate(&self, a: &[f32], b: &[f32], _: usize) -> f32 {
        sum_sq(a, b)
    }
    #[inline(always)]
    fn finish(&self, s: f32) -> f32 {
        s.sqrt()
    }
}

struct L2Sq;
impl Accumulator for L2Sq {
    #[inline(always)]
    fn accumulate(&self, a: &[f32], b: &[f32], _: usize) -> f32 {
        sum_sq(a, b)
    }
    #[inline(always)]
    fn finish(&self, s: f32) -> f32 {
        s
    }
}

struct Lp(f32);
impl Accumulator for Lp {
    #[inline(always)]
    fn accumulate(&self, a: &[f32], b: &[f32], _: usize) -> f32 {
        sum_lp(a, b, self.0)
    }
    #[inline(always)]
    fn finish(&self, s: f32) -> f32 {
        s.powf(1.0 / self.0)
    }
}

struct Maha<'a>(&'a [f32]);
impl Accumulator for Maha<'_> {
    #[inline(always)]
    fn accumulate(&self, a: &[f32], b: &[f32], offset: usize) -> f32 {
        sum_sq_w(a, b, &self.0[offset..offset + a.len()])
    }
    #[inline(always)]
    fn finish(&self, s: f32) -> f32 {
        s.sqrt()
    }
}

/// Elements between two early-abandon checks inside a block.
const CHECK: usize = 64;

/// Length of the per-node prefix copy kept for the search: the first check's span.
pub(crate) const fn prefix_len(dim: usize) -> usize {
    if dim < CHECK { dim } else { CHECK }
}

/// Inputs per segment of the summaries behind Manhattan's lower bound.
const SEGMENT: usize = 16;

/// Floats per block of a summary: one sum per segment of [`SEGMENT`] inputs, then Σ|w|.
const fn summary_block(dim: usize) -> usize {
    dim.div_ceil(SEGMENT) + 1
}

/// Length of a node's summary ([`summarise`]) over `depth` blocks.
pub(crate) const fn summary_len(dim: usize, depth: usize) -> usize {
    depth * summary_block(dim)
}

/// Writes the summary of `blocks` (a whole number of `dim`-float blocks) into `out`: per block,
/// the sum of every segment of [`SEGMENT`] inputs, then the block's L1 norm. For any two
/// vectors, Σ_segments |Σ q − Σ w| ≤ Σ |q − w| (triangle inequality), so two summaries give a
/// lower bound of the Manhattan distance from a few dozen floats instead of D.
pub(crate) fn summarise(blocks: &[f32], dim: usize, out: &mut [f32]) {
    let sb = summary_block(dim);
    for (block, out) in blocks.chunks_exact(dim).zip(out.chunks_exact_mut(sb)) {
        for (segment, o) in block.chunks(SEGMENT).zip(out.iter_mut()) {
            *o = segment.iter().sum();
        }
        out[sb - 1] = block.iter().map(|v| v.abs()).sum();
    }
}

/// True if the node with summary `node` is certainly farther than `bound` from the query with
/// summary `query` (Manhattan, blocks weighted by `alphas`), as [`bounded_distance`] computes
/// it. The lower bound is discounted by a bound on its own rounding error (segment sums: at
/// most SEGMENT·ε·Σ|v| each) and compared against `bound` inflated by the distance's rounding
/// error (at most (blocks·D + 4)·ε relative, all terms being non-negative), so a node is never
/// skipped that the exact scan would rank: results do not change, only the work.
#[inline(always)]
fn l1_bound_excludes(query: &[f32], node: &[f32], dim: usize, alphas: &[f32], bound: f32) -> bool {
    if !bound.is_finite() {
        return false;
    }
    let sb = summary_block(dim);
    // f32::EPSILON is twice the unit roundoff: a factor-2 margin on both error bounds.
    let eps = f32::EPSILON;
    let shrink = 1.0 - eps * (alphas.len() * dim + 4) as f32;
    let (mut lb, mut magnitude) = (0.0f32, 0.0f32);
    for (k, &alpha) in alphas.iter().enumerate() {
        let q = &query[k * sb..(k + 1) * sb];
        let w = &node[k * sb..(k + 1) * sb];
        lb += alpha * sum_l1(&q[..sb - 1], &w[..sb - 1]);
        magnitude += alpha * (q[sb - 1] + w[sb - 1]);
        // The first blocks alone already bound the distance from below (the others add
        // non-negative terms), with an error term of their own: stop once that suffices.
        let error = eps * (SEGMENT as f32 * magnitude + (sb as f32 + 2.0) * lb);
        if (lb - error) * shrink > bound {
            return true;
        }
    }
    false
}

/// True if (d, i) ranks before (e, j): smaller distance, ties to the smaller index. A NaN
/// distance (from values near the f32 limits: ∞ − ∞, 0 · ∞) ranks after every number, NaNs by
/// index, and before an empty slot (j = usize::MAX): the ranking is total, so a search over
/// n ≥ 2 nodes always finds a best and a second node. Without NaN the order is the plain one.
#[inline(always)]
fn before(d: f32, i: usize, e: f32, j: usize) -> bool {
    if d.is_nan() || e.is_nan() {
        return !d.is_nan() || j == usize::MAX || (e.is_nan() && i < j);
    }
    d < e || (d == e && i < j)
}

/// Running best and second-best (distance, index), ranked by `before`.
struct Ranking {
    best: (usize, f32),
    second: (usize, f32),
    want_second: bool,
}

impl Ranking {
    fn new(want_second: bool) -> Self {
        Ranking {
            best: (usize::MAX, f32::INFINITY),
            second: (usize::MAX, f32::INFINITY),
            want_second,
        }
    }

    /// Distance above which a node cannot enter the ranking.
    #[inline(always)]
    fn bound(&self) -> f32 {
        if self.want_second {
            self.second.1
        } else {
            self.best.1
        }
    }

    #[inline(always)]
    fn seen(&self, j: usize) -> bool {
        j == self.best.0 || j == self.second.0
    }

    #[inline(always)]
    fn offer(&mut self, j: usize, d: f32) {
        if before(d, j, self.best.1, self.best.0) {
            self.second = self.best;
            self.best = (j, d);
        } else if self.want_second && before(d, j, self.second.1, self.second.0) {
            self.second = (j, d);
        }
    }

    fn finish(self) -> Matches {
        Matches {
            best: self.best,
            second: (self.want_second && self.second.0 != usize::MAX).then_some(self.second),
        }
    }
}

/// The distance of one node, or `None` as soon as a lower bound exceeds `bound`. `prefix` holds
/// a copy of the node's first `prefix.len()` input-weight floats (the first check's span).
#[inline(always)]
fn bounded_distance<A: Accumulator>(
    acc: &A,
    node: &[f32],
    prefix: &[f32],
    query: &[f32],
    dim: usize,
    alphas: &[f32],
    bound: f32,
) -> Option<f32> {
    let mut total = 0.0f32;
    for (k, &alpha) in alphas.iter().enumerate() {
        let w = &node[k * dim..(k + 1) * dim];
        let q = &query[k * dim..(k + 1) * dim];
        let mut s = 0.0f32;
        let mut off = 0;
        while off < dim {
            let end = (off + CHECK).min(dim);
            // Same floats either way; the prefix copy is contiguous across nodes.
            let w_chunk = if k == 0 && off == 0 {
                prefix
            } else {
                &w[off..end]
            };
            s += acc.accumulate(&q[off..end], w_chunk, off);
            off = end;
            if total + alpha * acc.finish(s) > bound {
                return None;
            }
        }
        total += alpha * acc.finish(s);
    }
    Some(total)
}

#[inline(always)]
fn search_monotone<A: Accumulator>(
    acc: &A,
    buf: &NodeBuffer<'_>,
    query: &[f32],
    alphas: &[f32],
    want_second: bool,
    seeds: &[usize],
    query_summary: Option<&[f32]>,
) -> Option<Matches> {
    let dim = buf.dim;
    let stride = buf.depth * dim;
    let n = buf.weights.len() / stride.max(1);
    if n == 0 {
        return None;
    }
    let p = prefix_len(dim);
    debug_assert_eq!(buf.prefix.len(), n * p);
    let sl = summary_len(dim, buf.depth);
    debug_assert!(query_summary.is_none() || buf.summary.len() == n * sl);
    let mut rank = Ranking::new(want_second);
    // Likely winners first: a tight bound early makes the scan abandon most nodes quickly.
    // The ranking is by (distance, index), so the visiting order cannot change the result.
    for &j in seeds {
        if j < n && !rank.seen(j) {
            let node = &buf.weights[j * stride..(j + 1) * stride];
            let prefix = &buf.prefix[j * p..(j + 1) * p];
            let bound = rank.bound();
            if let Some(d) = bounded_distance(acc, node, prefix, query, dim, alphas, bound) {
                rank.offer(j, d);
            }
        }
    }
    for j in 0..n {
        if rank.seen(j) {
            continue;
        }
        if let Some(qs) = query_summary {
            let ns = &buf.summary[j * sl..(j + 1) * sl];
            if l1_bound_excludes(qs, ns, dim, alphas, rank.bound()) {
                continue;
            }
        }
        let node = &buf.weights[j * stride..(j + 1) * stride];
        let prefix = &buf.prefix[j * p..(j + 1) * p];
        if let Some(d) = bounded_distance(acc, node, prefix, query, dim, alphas, rank.bound()) {
            rank.offer(j, d);
        }
    }
    Some(rank.finish())
}

#[inline(always)]
fn search_cosine(
    buf: &NodeBuffer<'_>,
    query: &[f32],
    alphas: &[f32],
    want_second: bool,
) -> Option<Matches> {
    let dim = buf.dim;
    let stride = buf.depth * dim;
    let n = buf.weights.len() / stride.max(1);
    if n == 0 {
        return None;
    }
    let mut rank = Ranking::new(want_second);
    for j in 0..n {
        let node = &buf.weights[j * stride..(j + 1) * stride];
        let mut total = 0.0f32;
        for (k, &alpha) in alphas.iter().enumerate() {
            let (dot, na, nb) = dot_norms(
                &query[k * dim..(k + 1) * dim],
                &node[k * dim..(k + 1) * dim],
            );
            total += alpha * cosine_from(dot, na, nb);
        }
        rank.offer(j, total);
    }
    Some(rank.finish())
}

/// Finds the node(s) minimising d_j = Σ_k α_k · dist(query_k, node_{j,k}) over the first
/// `alphas.len()` blocks, ties going to the smaller index. `inv_var` is used by Mahalanobis only;
/// `seeds` are nodes to try first (a speed hint: the result does not depend on it).
pub(crate) fn search(
    metric: Metric,
    inv_var: &[f32],
    buf: &NodeBuffer<'_>,
    query: &[f32],
    alphas: &[f32],
    want_second: bool,
    seeds: &[usize],
) -> Option<Matches> {
    let kernels = Kernels::detect();
    search_with(
        kernels,
        metric,
        inv_var,
        buf,
        query,
        alphas,
        want_second,
        seeds,
    )
}

/// [`search`] in the copy of the kernels `kernels` selects (the same result in every copy).
#[allow(clippy::too_many_arguments)]
fn search_with(
    kernels: Kernels,
    metric: Metric,
    inv_var: &[f32],
    buf: &NodeBuffer<'_>,
    query: &[f32],
    alphas: &[f32],
    want_second: bool,
    seeds: &[usize],
) -> Option<Matches> {
    let k = kernels;
    debug_assert!(alphas.len() <= buf.depth);
    debug_assert!(query.len() >= alphas.len() * buf.dim);
    let w = want_second;
    match metric {
        Metric::Manhattan => {
            let blocks = alphas.len();
            let len = summary_len(buf.dim, blocks);
            // The query's summary: on the stack up to D ≈ 2.7k with K = 2 (no allocation).
            let mut stack = [0.0f32; 512];
            let mut heap = Vec::new();
            let qs = if len <= stack.len() {
                &mut stack[..len]
            } else {
                heap.resize(len, 0.0);
                &mut heap[..]
            };
            summarise(&query[..blocks * buf.dim], buf.dim, qs);
            let qs = &*qs;
            dispatch!(
                k,
                search_monotone(&L1, buf, query, alphas, w, seeds, Some(qs))
            )
        }
        Metric::Euclidean => dispatch!(k, search_monotone(&L2, buf, query, alphas, w, seeds, None)),
        Metric::SquaredEuclidean => {
            dispatch!(
                k,
                search_monotone(&L2Sq, buf, query, alphas, w, seeds, None)
            )
        }
        Metric::Minkowski { p } => {
            dispatch!(
                k,
                search_monotone(&Lp(p), buf, query, alphas, w, seeds, None)
            )
        }
        Metric::Mahalanobis => {
            dispatch!(
                k,
                search_monotone(&Maha(inv_var), buf, query, alphas, w, seeds, None)
            )
        }
        Metric::Cosine => dispatch!(k, search_cosine(buf, query, alphas, w)),
    }
}

/// The distance of one node (all `alphas.len()` blocks), computed block by block.
#[cfg(test)]
pub(crate) fn node_distance(
    metric: Metric,
    inv_var: &[f32],
    node: &[f32],
    query: &[f32],
    dim: usize,
    alphas: &[f32],
) -> f32 {
    let mut total = 0.0f32;
    for (k, &alpha) in alphas.iter().enumerate() {
        let w = &node[k * dim..(k + 1) * dim];
        let q = &query[k * dim..(k + 1) * dim];
        let d = match metric {
            Metric::Manhattan => manhattan(q, w),
            Metric::Euclidean => euclidean(q, w),
            Metric::SquaredEuclidean => squared_euclidean(q, w),
            Metric::Minkowski { p } => minkowski(q, w, p),
            Metric::Mahalanobis => mahalanobis_diagonal(q, w, inv_var),
            Metric::Cosine => cosine(q, w),
        };
        total += alpha * d;
    }
    total
}

/// Running per-feature mean and variance (Welford, f64) for the Mahalanobis metric.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RunningStats {
    pub count: u64,
    pub mean: Vec<f64>,
    pub m2: Vec<f64>,
    /// 1 / (variance + 1e-6), or 1 before the second observation.
    pub inv_var: Vec<f32>,
}

impl RunningStats {
    pub const VARIANCE_FLOOR: f64 = 1e-6;

    pub fn new(dim: usize) -> Self {
        RunningStats {
            count: 0,
            mean: vec![0.0; dim],
            m2: vec![0.0; dim],
            inv_var: vec![1.0; dim],
        }
    }

    pub fn observe(&mut self, x: &[f32]) {
        // Saturating: a count read from a checkpoint may be anything.
        self.count = self.count.saturating_add(1);
        let n = self.count as f64;
        for ((m, m2), &v) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(x) {
            let v = v as f64;
            let delta = v - *m;
            *m += delta / n;
            *m2 += delta * (v - *m);
        }
        self.refresh();
    }

    pub fn refresh(&mut self) {
        if self.count < 2 {
            self.inv_var.iter_mut().for_each(|v| *v = 1.0);
            return;
        }
        let denom = (self.count - 1) as f64;
        for (iv, m2) in self.inv_var.iter_mut().zip(&self.m2) {
            *iv = (1.0 / (m2 / denom + Self::VARIANCE_FLOOR)) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-5 * (1.0 + b.abs())
    }

    #[test]
    fn metrics_match_hand_computed_values() {
        let a = [1.0, -2.0, 3.0, 0.5];
        let b = [4.0, 2.0, 3.0, -0.5];
        // differences: -3, -4, 0, 1
        assert!(close(manhattan(&a, &b), 8.0));
        assert!(close(squared_euclidean(&a, &b), 26.0));
        assert!(close(euclidean(&a, &b), 26f32.sqrt()));
        assert!(close(
            minkowski(&a, &b, 3.0),
            (27.0f32 + 64.0 + 1.0).powf(1.0 / 3.0)
        ));
        assert!(close(minkowski(&a, &b, 1.0), 8.0));
        assert!(close(minkowski(&a, &b, 2.0), 26f32.sqrt()));
        // a·b = 4 - 4 + 9 - 0.25 = 8.75; |a|² = 14.25; |b|² = 29.25
        let expect = 1.0 - 8.75 / (14.25f32.sqrt() * 29.25f32.sqrt());
        assert!(close(cosine(&a, &b), expect));
        assert!(close(cosine(&a, &a), 0.0));
        assert!(close(cosine(&[1.0, 0.0], &[-1.0, 0.0]), 2.0));
        assert_eq!(cosine(&[0.0, 0.0], &[0.0, 0.0]), 0.0);
        assert_eq!(cosine(&[0.0, 0.0], &[1.0, 0.0]), 1.0);
        let iv = [1.0, 0.25, 2.0, 4.0];
        // 9·1 + 16·0.25 + 0 + 1·4 = 17
        assert!(close(mahalanobis_diagonal(&a, &b, &iv), 17f32.sqrt()));
        assert_eq!(Metric::Mahalanobis.distance(&a, &b), euclidean(&a, &b));
    }

    #[test]
    fn lane_kernels_agree_with_naive_sums_on_long_vectors() {
        let a: Vec<f32> = (0..675).map(|i| ((i * 37) % 101) as f32 * 0.01).collect();
        let b: Vec<f32> = (0..675).map(|i| ((i * 53) % 97) as f32 * 0.01).collect();
        let l1: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).abs() as f64).sum();
        let l2: f64 = a
            .iter()
            .zip(&b)
            .map(|(x, y)| ((x - y) * (x - y)) as f64)
            .sum();
        assert!((manhattan(&a, &b) as f64 - l1).abs() < 1e-3 * l1);
        assert!((squared_euclidean(&a, &b) as f64 - l2).abs() < 1e-3 * l2);
    }

    /// Random floats over many magnitudes and both signs (xorshift; the test is deterministic).
    fn wide_floats(n: usize, state: &mut u64) -> Vec<f32> {
        (0..n)
            .map(|_| {
                *state ^= *state << 13;
                *state ^= *state >> 7;
                *state ^= *state << 17;
                let mantissa = (*state >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
                let exponent = ((*state >> 8) % 24) as i32 - 12;
                mantissa * 2f32.powi(exponent)
            })
            .collect()
    }

    #[test]
    fn dispatched_kernels_are_bit_identical_to_portable_ones() {
        let k = Kernels::detect();
        eprintln!("kernels in use: {k:?}");
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for len in [1, 7, 8, 9, 63, 64, 65, 256, 675, 768, 2025, 4099] {
            for _ in 0..20 {
                let a = wide_floats(len, &mut state);
                let b = wide_floats(len, &mut state);
                let w: Vec<f32> = wide_floats(len, &mut state)
                    .iter()
                    .map(|v| v.abs())
                    .collect();
                let bits = |v: f32| v.to_bits();
                assert_eq!(
                    bits(dispatch!(k, sum_l1(&a, &b))),
                    bits(sum_l1(&a, &b)),
                    "{len}"
                );
                assert_eq!(
                    bits(dispatch!(k, sum_sq(&a, &b))),
                    bits(sum_sq(&a, &b)),
                    "{len}"
                );
                assert_eq!(
                    bits(dispatch!(k, sum_sq_w(&a, &b, &w))),
                    bits(sum_sq_w(&a, &b, &w)),
                    "{len}"
                );
                let (d, x, y) = dispatch!(k, dot_norms(&a, &b));
                let (d0, x0, y0) = dot_norms(&a, &b);
                assert_eq!(
                    (bits(d), bits(x), bits(y)),
                    (bits(d0), bits(x0), bits(y0)),
                    "{len}"
                );
                assert_eq!(bits(manhattan(&a, &b)), bits(sum_l1(&a, &b)));
            }
        }
    }

    #[test]
    fn dispatched_search_finds_the_same_matches_as_the_portable_one() {
        let k = Kernels::detect();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for (dim, n) in [(256usize, 790usize), (675, 200), (13, 300)] {
            let depth = 3;
            // Clustered nodes (near copies of a few centres, so that the early abandoning
            // matters) and unrelated ones.
            let centres = wide_floats(5 * depth * dim, &mut state);
            let mut weights = Vec::with_capacity(n * depth * dim);
            for j in 0..n {
                let noise = wide_floats(depth * dim, &mut state);
                if j % 2 == 0 {
                    let c = &centres[(j % 5) * depth * dim..(j % 5 + 1) * depth * dim];
                    weights.extend(c.iter().zip(&noise).map(|(c, e)| c + 1e-3 * e));
                } else {
                    weights.extend(noise);
                }
            }
            let p = prefix_len(dim);
            let prefix: Vec<f32> = weights
                .chunks(depth * dim)
                .flat_map(|node| node[..p].to_vec())
                .collect();
            let sl = summary_len(dim, depth);
            let mut summary = vec![0.0; n * sl];
            for (node, out) in weights.chunks(depth * dim).zip(summary.chunks_mut(sl)) {
                summarise(node, dim, out);
            }
            let buf = NodeBuffer {
                prefix: &prefix,
                summary: &summary,
                weights: &weights,
                dim,
                depth,
            };
            let iv: Vec<f32> = wide_floats(dim, &mut state)
                .iter()
                .map(|v| v.abs())
                .collect();
            for trial in 0..12 {
                let q: Vec<f32> = if trial % 2 == 0 {
                    let j = (trial * 37) % n;
                    let noise = wide_floats(depth * dim, &mut state);
                    weights[j * depth * dim..(j + 1) * depth * dim]
                        .iter()
                        .zip(&noise)
                        .map(|(w, e)| w + 1e-4 * e)
                        .collect()
                } else {
                    wide_floats(depth * dim, &mut state)
                };
                for metric in [
                    Metric::Manhattan,
                    Metric::Euclidean,
                    Metric::SquaredEuclidean,
                    Metric::Minkowski { p: 3.0 },
                    Metric::Cosine,
                    Metric::Mahalanobis,
                ] {
                    for alphas in [&[0.665f32, 0.245, 0.090][..], &[1.0][..]] {
                        for want_second in [true, false] {
                            let seeds = [(trial * 11) % n];
                            let args = (metric, &iv[..], &buf, &q[..], alphas, want_second);
                            let fast = search_with(
                                k, args.0, args.1, args.2, args.3, args.4, args.5, &seeds,
                            );
                            let slow = search_with(
                                Kernels::Portable,
                                args.0,
                                args.1,
                                args.2,
                                args.3,
                                args.4,
                                args.5,
                                &seeds,
                            );
                            let (fast, slow) = (fast.unwrap(), slow.unwrap());
                            assert_eq!(fast.best.0, slow.best.0, "{metric:?} {dim} {trial}");
                            assert_eq!(fast.best.1.to_bits(), slow.best.1.to_bits());
                            assert_eq!(
                                fast.second.map(|(j, d)| (j, d.to_bits())),
                                slow.second.map(|(j, d)| (j, d.to_bits())),
                                "{metric:?} {dim} {trial}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn running_stats_give_inverse_variance() {
        let mut s = RunningStats::new(2);
        s.observe(&[1.0, 5.0]);
        assert_eq!(s.inv_var, vec![1.0, 1.0]);
        s.observe(&[3.0, 5.0]);
        s.observe(&[5.0, 5.0]);
        // variance of (1, 3, 5) = 4; of (5, 5, 5) = 0
        assert!(close(s.inv_var[0], 1.0 / (4.0 + 1e-6)));
        assert!(close(s.inv_var[1], 1e6));
    }

    fn brute(metric: Metric, buf: &NodeBuffer<'_>, q: &[f32], alphas: &[f32]) -> Vec<(f32, usize)> {
        let stride = buf.depth * buf.dim;
        let iv = vec![0.5; buf.dim];
        let mut all: Vec<(f32, usize)> = (0..buf.weights.len() / stride)
            .map(|j| {
                let node = &buf.weights[j * stride..(j + 1) * stride];
                (node_distance(metric, &iv, node, q, buf.dim, alphas), j)
            })
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all
    }

    #[test]
    fn early_abandon_search_equals_brute_force() {
        // At 3000 the query's Manhattan summary no longer fits the search's stack buffer.
        for dim in [300, 3000] {
            search_equals_brute(dim);
        }
    }

    fn search_equals_brute(dim: usize) {
        let depth = 3;
        let n = 40;
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        let weights: Vec<f32> = (0..n * depth * dim).map(|_| next()).collect();
        let q: Vec<f32> = (0..depth * dim).map(|_| next()).collect();
        let p = prefix_len(dim);
        let prefix: Vec<f32> = weights
            .chunks(depth * dim)
            .flat_map(|node| node[..p].to_vec())
            .collect();
        let sl = summary_len(dim, depth);
        let mut summary = vec![0.0; n * sl];
        for (node, out) in weights.chunks(depth * dim).zip(summary.chunks_mut(sl)) {
            summarise(node, dim, out);
        }
        let buf = NodeBuffer {
            prefix: &prefix,
            summary: &summary,
            weights: &weights,
            dim,
            depth,
        };
        let iv = vec![0.5; dim];
        for metric in [
            Metric::Manhattan,
            Metric::Euclidean,
            Metric::SquaredEuclidean,
            Metric::Minkowski { p: 3.0 },
            Metric::Cosine,
            Metric::Mahalanobis,
        ] {
            for alphas in [&[0.665f32, 0.245, 0.090][..], &[1.0][..]] {
                let m = search(metric, &iv, &buf, &q, alphas, true, &[]).unwrap();
                let want = brute(metric, &buf, &q, alphas);
                // Seeds (including repeats and out-of-range ones) are only a speed hint.
                for seeds in [
                    &[want[0].1, 7, 7, 999][..],
                    &[want[1].1, want[0].1],
                    &[n - 1],
                ] {
                    let seeded = search(metric, &iv, &buf, &q, alphas, true, seeds);
                    assert_eq!(seeded.unwrap(), m, "{metric:?} {seeds:?}");
                }
                assert_eq!(m.best.0, want[0].1, "{metric:?}");
                assert!(close(m.best.1, want[0].0), "{metric:?}");
                assert_eq!(m.second.unwrap().0, want[1].1, "{metric:?}");
                let one = search(metric, &iv, &buf, &q, alphas, false, &[3]).unwrap();
                assert_eq!(one.best.0, want[0].1);
                assert!(one.second.is_none());
            }
        }
    }

    #[test]
    fn nan_distances_rank_last_and_never_leave_the_ranking_empty() {
        let mut r = Ranking::new(true);
        for (j, d) in [
            (0, f32::NAN),
            (1, 2.0),
            (2, f32::NAN),
            (3, 1.0),
            (4, f32::INFINITY),
        ] {
            r.offer(j, d);
        }
        let m = r.finish();
        assert_eq!((m.best, m.second), ((3, 1.0), Some((1, 2.0))));
        let mut r = Ranking::new(true);
        for (j, d) in [(0, f32::NAN), (1, f32::NAN), (2, 5.0)] {
            r.offer(j, d);
        }
        let m = r.finish();
        assert_eq!(m.best, (2, 5.0));
        assert_eq!(m.second.unwrap().0, 0);
        // All NaN (e.g. 0 · ∞ in every node): still a best and a second node, by index.
        let mut r = Ranking::new(true);
        for j in [4, 2, 7] {
            r.offer(j, f32::NAN);
        }
        let m = r.finish();
        assert_eq!((m.best.0, m.second.unwrap().0), (2, 4));
        // The search over f32-limit weights where Mahalanobis gives ∞ · 0 = NaN everywhere.
        let weights = [3.0e38f32, -3.0e38, 3.0e38, 2.0e38];
        let prefix = weights;
        let mut summary = vec![0.0; 4 * summary_len(1, 1)];
        for (node, out) in weights.chunks(1).zip(summary.chunks_mut(summary_len(1, 1))) {
            summarise(node, 1, out);
        }
        let buf = NodeBuffer {
            prefix: &prefix,
            summary: &summary,
            weights: &weights,
            dim: 1,
            depth: 1,
        };
        let m = search(
            Metric::Mahalanobis,
            &[0.0],
            &buf,
            &[-3.0e38],
            &[1.0],
            true,
            &[],
        )
        .unwrap();
        assert_eq!((m.best.0, m.second.unwrap().0), (1, 0));
    }

    #[test]
    fn manhattan_lower_bound_never_excludes_a_node_within_the_bound() {
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32 - 0.5
        };
        let alphas = [0.665f32, 0.245, 0.090];
        let mut excluded = 0;
        for (dim, scale) in [(675usize, 1.0f32), (256, 1000.0), (5, 0.001), (17, 1.0)] {
            let sl = summary_len(dim, alphas.len());
            for trial in 0..200 {
                let q: Vec<f32> = (0..3 * dim).map(|_| scale * next()).collect();
                // Near copies (the hard case for rounding), unrelated vectors, and shifted
                // copies (whose segment sums carry the whole distance).
                let w: Vec<f32> = match trial % 3 {
                    0 => q.iter().map(|v| v + scale * 1e-4 * next()).collect(),
                    1 => (0..3 * dim).map(|_| scale * next()).collect(),
                    _ => q.iter().map(|v| v + 0.25 * scale).collect(),
                };
                let (mut qs, mut ws) = (vec![0.0; sl], vec![0.0; sl]);
                summarise(&q, dim, &mut qs);
                summarise(&w, dim, &mut ws);
                let p = prefix_len(dim);
                let d =
                    bounded_distance(&L1, &w, &w[..p], &q, dim, &alphas, f32::INFINITY).unwrap();
                assert!(
                    !l1_bound_excludes(&qs, &ws, dim, &alphas, d),
                    "{dim} {trial}"
                );
                assert!(!l1_bound_excludes(&qs, &ws, dim, &alphas, f32::INFINITY));
                if trial % 3 == 2 && l1_bound_excludes(&qs, &ws, dim, &alphas, 0.5 * d) {
                    excluded += 1;
                }
            }
        }
        // The bound is useful: shifted copies are excluded at half their distance.
        assert_eq!(excluded, 4 * 66);
    }
}
