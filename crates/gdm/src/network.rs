//! The Gamma-GWR network: a growing self-organising network whose nodes carry an input weight,
//! K temporal context vectors, a habituation counter, label histograms, undirected aged edges
//! and directed temporal synapses (docs/DESIGN.md §3, steps 1–7).
//!
//! Storage: node j's weight and contexts are one block `[w_j, c_j1, …, c_jK]` of (K+1)·D floats
//! in a single contiguous buffer; edges are adjacency lists (each edge stored at both ends with
//! the same age); synapses are sparse per-node lists sorted by target; label histograms are
//! sparse per-node lists sorted by label. Node indices are dense `0..len()`; removals compact
//! the buffers and remap every edge and synapse.
//!
//! A network starts empty: its first two training samples become its first two nodes (weight =
//! sample, contexts = the global context at that step, habituation 1, histograms = the sample's
//! labels), joined by an edge. From then on every sample either updates the best-matching node
//! or inserts a new one.
//!
//! ```
//! use lgdm_gdm::{GammaGwr, MemoryParams, Metric, Supervision};
//! let params = MemoryParams { context_depth: 1, ..MemoryParams::default() };
//! let mut net = GammaGwr::new(params, Metric::Manhattan, 2, 1).unwrap();
//! for (i, x) in [[0.0, 0.0], [1.0, 1.0], [0.1, 0.0]].iter().enumerate() {
//!     net.train_step(x, &[Some(i as u32 % 2)], Supervision::Unsupervised).unwrap();
//! }
//! assert!(net.len() >= 2);
//! net.check_consistency().unwrap();
//! assert!(net.train_step(&[f32::NAN, 0.0], &[None], Supervision::Unsupervised).is_err());
//! ```

use crate::config::{MAX_LEVELS, MemoryParams};
use crate::error::{ConfigError, GdmError};
use crate::metric::{self, Matches, Metric, NodeBuffer, RunningStats};

/// An undirected edge as seen from one of its ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// Index of the node at the other end.
    pub to: u32,
    /// Age: firings of either end's owner since the edge was created or refreshed.
    pub age: u32,
}

/// A sparse, open-ended label histogram: `(label, count)` pairs sorted by label, counts > 0.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Histogram {
    entries: Vec<(u32, f32)>,
}

impl Histogram {
    /// A histogram holding `increment` for `label`, or an empty one.
    pub(crate) fn start(label: Option<u32>, increment: f32) -> Self {
        Histogram {
            entries: label.map(|l| vec![(l, increment)]).unwrap_or_default(),
        }
    }

    pub(crate) fn from_entries(entries: Vec<(u32, f32)>) -> Self {
        Histogram { entries }
    }

    /// The `(label, count)` pairs, sorted by label; every count is > 0.
    pub fn entries(&self) -> &[(u32, f32)] {
        &self.entries
    }

    /// Count of `label` (0 if absent).
    pub fn get(&self, label: u32) -> f32 {
        self.entries
            .binary_search_by_key(&label, |e| e.0)
            .map(|i| self.entries[i].1)
            .unwrap_or(0.0)
    }

    /// The label with the highest count (ties: the smallest label), `None` if empty.
    pub fn argmax(&self) -> Option<u32> {
        let mut best: Option<(u32, f32)> = None;
        for &(l, v) in &self.entries {
            if best.is_none_or(|(_, bv)| v > bv) {
                best = Some((l, v));
            }
        }
        best.map(|b| b.0)
    }

    /// histogram[label] += increment; every other count −= decrement, floored at 0 (zero
    /// entries are dropped).
    pub(crate) fn reinforce(&mut self, label: u32, increment: f32, decrement: f32) {
        let mut found = false;
        for (l, v) in self.entries.iter_mut() {
            if *l == label {
                *v += increment;
                found = true;
            } else {
                *v = (*v - decrement).max(0.0);
            }
        }
        self.entries.retain(|e| e.1 > 0.0);
        if !found {
            let at = self.entries.partition_point(|e| e.0 < label);
            self.entries.insert(at, (label, increment));
        }
    }
}

/// How a training step uses its labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Supervision {
    /// Growth ignores labels (episodic memory); labels only update histograms.
    Unsupervised,
    /// Growth is regulated by the level-0 label (semantic memory): a wrong prediction may insert,
    /// or else updates at ε·mod_rate without label update; a right prediction updates normally.
    /// Without a level-0 label the step updates normally, never inserts, touches no histogram.
    Regulated,
}

/// What one training step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutcome {
    /// Best-matching node b and its distance d_b (`None` while the first two nodes are made).
    pub best: Option<(usize, f32)>,
    /// The node that represents the sample: the new node after an insertion, else b.
    pub node: usize,
    /// Whether a node was created.
    pub inserted: bool,
}

/// Temporal state of a stream: the previous best node's block (for the global context) and the
/// node that represented the previous sample (for temporal synapses).
#[derive(Debug, Clone)]
pub(crate) struct ContextState {
    /// Block [w_b, c_b1..c_bK] of the previous step's best node; zero at a sequence start.
    pub prev_block: Vec<f32>,
    /// Scratch: the global context [x, C_1..C_K] of the current step.
    pub global: Vec<f32>,
    /// Node that represented the previous sample of the sequence.
    pub prev_node: Option<u32>,
    /// Speed hint only (not saved, not compared): the previous step's best node.
    pub prev_best: Option<u32>,
    /// Speed hint only (not saved, not compared), used by the next training step and then
    /// cleared: a node the caller expects near the best match.
    pub hint: Option<u32>,
    /// Scratch: nodes the search tries first.
    pub seeds: Vec<usize>,
}

/// Equality ignores the scratch buffers and the speed hint (they never change a result).
impl PartialEq for ContextState {
    fn eq(&self, other: &Self) -> bool {
        self.prev_block == other.prev_block && self.prev_node == other.prev_node
    }
}

impl ContextState {
    pub fn new(dim: usize, depth: usize) -> Self {
        ContextState {
            prev_block: vec![0.0; dim * depth],
            global: vec![0.0; dim * depth],
            prev_node: None,
            prev_best: None,
            hint: None,
            seeds: Vec::new(),
        }
    }

    /// Starts a new sequence: all contexts zero, no previous node.
    pub fn reset(&mut self) {
        self.prev_block.fill(0.0);
        self.prev_node = None;
        self.prev_best = None;
        self.hint = None;
    }

    /// C_0 = x; C_k = β·c_{b,k}(t−1) + (1−β)·c_{b,k−1}(t−1), with c_{b,0} ≡ w_b.
    pub fn compute_global(&mut self, x: &[f32], beta: f32, dim: usize, depth: usize) {
        self.global[..dim].copy_from_slice(x);
        for k in 1..depth {
            let (prev_lo, prev_k) = self.prev_block.split_at(k * dim);
            let prev_km1 = &prev_lo[(k - 1) * dim..];
            let prev_k = &prev_k[..dim];
            let g = &mut self.global[k * dim..(k + 1) * dim];
            for ((g, &pk), &pkm1) in g.iter_mut().zip(prev_k).zip(prev_km1) {
                *g = beta * pk + (1.0 - beta) * pkm1;
            }
        }
    }
}

/// A Gamma-GWR network (see the module docs).
#[derive(Clone, PartialEq)]
pub struct GammaGwr {
    pub(crate) params: MemoryParams,
    pub(crate) metric: Metric,
    pub(crate) alphas: Vec<f32>,
    pub(crate) dim: usize,
    pub(crate) depth: usize,
    pub(crate) weights: Vec<f32>,
    /// Search cache: each node's first `prefix_len(dim)` weight floats, contiguous. Derived
    /// from `weights` (kept in sync by every change; not saved).
    pub(crate) prefix: Vec<f32>,
    /// Search cache: each node's `summary_len(dim, depth)` floats (segment sums and block
    /// norms, for Manhattan's lower bound), contiguous. Derived from `weights` like `prefix`.
    pub(crate) summary: Vec<f32>,
    pub(crate) habituation: Vec<f32>,
    pub(crate) edges: Vec<Vec<Edge>>,
    pub(crate) synapses: Vec<Vec<(u32, u32)>>,
    /// `labels[level][node]`.
    pub(crate) labels: Vec<Vec<Histogram>>,
    pub(crate) stats: Option<RunningStats>,
    pub(crate) train_ctx: ContextState,
}

const NO_CONTEXT_ALPHAS: [f32; 1] = [1.0];

/// A summary: the buffers are far too large to print.
impl std::fmt::Debug for GammaGwr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GammaGwr")
            .field("nodes", &self.len())
            .field("edges", &self.edge_count())
            .field("dim", &self.dim)
            .field("context_depth", &self.context_depth())
            .field("levels", &self.levels())
            .field("metric", &self.metric)
            .finish_non_exhaustive()
    }
}

impl GammaGwr {
    /// An empty network for `dim`-dimensional inputs (1 ≤ `dim` ≤
    /// [`MAX_DIM`](crate::config::MAX_DIM)) with `levels` label levels (1 ≤ `levels` ≤
    /// [`MAX_LEVELS`]).
    pub fn new(
        params: MemoryParams,
        metric: Metric,
        dim: usize,
        levels: usize,
    ) -> Result<Self, GdmError> {
        crate::dual::check_dim(dim)?;
        metric.validate()?;
        params.validate("memory")?;
        if levels == 0 {
            return Err(ConfigError::invalid("levels", "at least one label level").into());
        }
        if levels > MAX_LEVELS {
            return Err(ConfigError::invalid(
                "levels",
                format!("{levels} is larger than {MAX_LEVELS}"),
            )
            .into());
        }
        let depth = params.context_depth + 1;
        Ok(GammaGwr {
            alphas: params.context_weights(),
            metric,
            dim,
            depth,
            weights: Vec::new(),
            prefix: Vec::new(),
            summary: Vec::new(),
            habituation: Vec::new(),
            edges: Vec::new(),
            synapses: Vec::new(),
            labels: vec![Vec::new(); levels],
            stats: (metric == Metric::Mahalanobis).then(|| RunningStats::new(dim)),
            train_ctx: ContextState::new(dim, depth),
            params,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.habituation.len()
    }

    /// True if the network has no node yet.
    pub fn is_empty(&self) -> bool {
        self.habituation.is_empty()
    }

    /// Input dimension D.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number K of context descriptors per node.
    pub fn context_depth(&self) -> usize {
        self.depth - 1
    }

    /// Number of label levels.
    pub fn levels(&self) -> usize {
        self.labels.len()
    }

    /// The hyperparameters.
    pub fn params(&self) -> &MemoryParams {
        &self.params
    }

    /// The distance metric.
    pub fn metric(&self) -> Metric {
        self.metric
    }

    /// Context weights α_0..α_K in use.
    pub fn alphas(&self) -> &[f32] {
        &self.alphas
    }

    fn stride(&self) -> usize {
        self.depth * self.dim
    }

    /// Node `j`'s whole block `[w_j, c_j1, …, c_jK]`. Panics if `j >= len()`.
    pub fn node_block(&self, j: usize) -> &[f32] {
        let s = self.stride();
        &self.weights[j * s..(j + 1) * s]
    }

    /// Node `j`'s input weight w_j. Panics if `j >= len()`.
    pub fn weight(&self, j: usize) -> &[f32] {
        let s = self.stride();
        &self.weights[j * s..j * s + self.dim]
    }

    /// Node `j`'s context vector c_{j,k}, k in 1..=K. Panics if out of range.
    pub fn context(&self, j: usize, k: usize) -> &[f32] {
        assert!(
            k >= 1 && k < self.depth,
            "context index {k} out of 1..={}",
            self.depth - 1
        );
        &self.node_block(j)[k * self.dim..(k + 1) * self.dim]
    }

    /// Node `j`'s habituation counter h_j in (0, 1].
    pub fn habituation(&self, j: usize) -> f32 {
        self.habituation[j]
    }

    /// Node `j`'s edges.
    pub fn edges(&self, j: usize) -> &[Edge] {
        &self.edges[j]
    }

    /// Number of undirected edges.
    pub fn edge_count(&self) -> usize {
        self.edges.iter().map(Vec::len).sum::<usize>() / 2
    }

    /// The age of edge i–j, `None` if there is no such edge.
    pub fn edge_age(&self, i: usize, j: usize) -> Option<u32> {
        self.edges
            .get(i)?
            .iter()
            .find(|e| e.to as usize == j)
            .map(|e| e.age)
    }

    /// Node `j`'s outgoing temporal synapses `(target, count)`, sorted by target.
    pub fn synapses(&self, j: usize) -> &[(u32, u32)] {
        &self.synapses[j]
    }

    /// Count of the temporal synapse P(i → j).
    pub fn synapse(&self, i: usize, j: usize) -> u32 {
        self.synapses[i]
            .binary_search_by_key(&(j as u32), |e| e.0)
            .map(|at| self.synapses[i][at].1)
            .unwrap_or(0)
    }

    /// argmax_j P(i → j) (ties: the smallest j), `None` if node `i` has no outgoing synapse.
    pub fn successor(&self, i: usize) -> Option<usize> {
        let mut best: Option<(u32, u32)> = None;
        for &(to, c) in &self.synapses[i] {
            if best.is_none_or(|(_, bc)| c > bc) {
                best = Some((to, c));
            }
        }
        best.map(|b| b.0 as usize)
    }

    /// Node `j`'s histogram at label level `level`.
    pub fn histogram(&self, level: usize, j: usize) -> &Histogram {
        &self.labels[level][j]
    }

    /// Node `j`'s label at `level` (histogram argmax).
    pub fn label(&self, level: usize, j: usize) -> Option<u32> {
        self.labels[level][j].argmax()
    }

    fn inv_var(&self) -> &[f32] {
        self.stats.as_ref().map_or(&[], |s| &s.inv_var)
    }

    fn buffer(&self) -> NodeBuffer<'_> {
        NodeBuffer {
            weights: &self.weights,
            prefix: &self.prefix,
            summary: &self.summary,
            dim: self.dim,
            depth: self.depth,
        }
    }

    /// Fills `seeds` with the nodes likely to match next: the previous best and representing
    /// nodes, their neighbours and their strongest temporal successors.
    fn fill_seeds(&self, prev: [Option<u32>; 3], seeds: &mut Vec<usize>) {
        seeds.clear();
        for p in prev.into_iter().flatten() {
            let p = p as usize;
            if p >= self.len() {
                continue;
            }
            seeds.push(p);
            if let Some(next) = self.successor(p) {
                seeds.push(next);
            }
            seeds.extend(self.edges[p].iter().map(|e| e.to as usize));
        }
    }

    /// A speed hint for the next training step only: node `j` (with its neighbours and
    /// successor) is tried first by the search. The step's result does not depend on it.
    pub(crate) fn hint_next(&mut self, j: usize) {
        self.train_ctx.hint = Some(j as u32);
    }

    /// Starts a new training sequence: contexts reset to zero, no temporal synapse from the
    /// previous sample.
    pub fn begin_sequence(&mut self) {
        self.train_ctx.reset();
    }

    /// One training step on input `x` (length D, finite values) with `labels[level]` the
    /// optional label of each level (missing levels count as unlabelled; extra entries are
    /// ignored). A wrong length or a non-finite value is an error (reported as sample 0), and the
    /// network is then unchanged.
    pub fn train_step(
        &mut self,
        x: &[f32],
        labels: &[Option<u32>],
        supervision: Supervision,
    ) -> Result<StepOutcome, GdmError> {
        if x.len() != self.dim {
            return Err(GdmError::DimensionMismatch {
                sample: 0,
                expected: self.dim,
                found: x.len(),
            });
        }
        if let Some(position) = x.iter().position(|v| !v.is_finite()) {
            return Err(GdmError::NonFinite {
                sample: 0,
                position,
            });
        }
        Ok(self.step(x, labels, supervision))
    }

    /// [`GammaGwr::train_step`] without input checks (`x` must have length D and be finite).
    pub(crate) fn step(
        &mut self,
        x: &[f32],
        labels: &[Option<u32>],
        supervision: Supervision,
    ) -> StepOutcome {
        debug_assert_eq!(x.len(), self.dim);
        if let Some(stats) = &mut self.stats {
            stats.observe(x);
        }
        let (dim, depth) = (self.dim, self.depth);
        self.train_ctx
            .compute_global(x, self.params.beta, dim, depth);
        let n = self.len();
        if n < 2 {
            let r = self.push_node_from_global(labels);
            if n == 1 {
                self.connect(0, 1);
            }
            self.link_temporal(r);
            let s = self.stride();
            self.train_ctx
                .prev_block
                .copy_from_slice(&self.weights[r * s..(r + 1) * s]);
            return StepOutcome {
                best: None,
                node: r,
                inserted: true,
            };
        }
        let mut seeds = std::mem::take(&mut self.train_ctx.seeds);
        let hint = self.train_ctx.hint.take();
        self.fill_seeds(
            [hint, self.train_ctx.prev_best, self.train_ctx.prev_node],
            &mut seeds,
        );
        let Matches { best, second } = metric::search(
            self.metric,
            self.inv_var(),
            &self.buffer(),
            &self.train_ctx.global,
            &self.alphas,
            true,
            &seeds,
        )
        .expect("network has nodes");
        self.train_ctx.seeds = seeds;
        let (b, d_b) = best;
        self.train_ctx.prev_best = Some(b as u32);
        let s_node = second.expect("network has two nodes").0;
        let stride = self.stride();
        // The context of the next step comes from b as it was matched (before its update).
        self.train_ctx
            .prev_block
            .copy_from_slice(&self.weights[b * stride..(b + 1) * stride]);

        let p = &self.params;
        let activity = (-d_b).exp();
        let truth = labels.first().copied().flatten();
        let (may_insert, mispredicted) = match supervision {
            Supervision::Unsupervised => (true, false),
            Supervision::Regulated => {
                let wrong = truth.is_some() && self.labels[0][b].argmax() != truth;
                (wrong, wrong)
            }
        };
        let room = p.max_nodes.is_none_or(|m| n < m);
        let node = if may_insert
            && activity < p.activation_threshold
            && self.habituation[b] < p.habituation_threshold
            && room
        {
            self.insert(b, s_node, labels)
        } else {
            let (rate_b, rate_n) = if mispredicted {
                (p.epsilon_b * p.mod_rate, p.epsilon_n * p.mod_rate)
            } else {
                (p.epsilon_b, p.epsilon_n)
            };
            self.update(b, s_node, rate_b, rate_n);
            if !mispredicted {
                let (inc, dec) = (self.params.label_increment, self.params.label_decrement);
                for (level, hists) in self.labels.iter_mut().enumerate() {
                    if let Some(y) = labels.get(level).copied().flatten() {
                        hists[b].reinforce(y, inc, dec);
                    }
                }
            }
            b
        };
        self.link_temporal(node);
        StepOutcome {
            best: Some((b, d_b)),
            node,
            inserted: node != b,
        }
    }

    /// h ← h + τ·κ·(1 − h) − τ.
    fn habituate(&mut self, j: usize, tau: f32) {
        let h = self.habituation[j];
        self.habituation[j] = h + tau * self.params.kappa * (1.0 - h) - tau;
    }

    fn move_towards(weights: &mut [f32], target: &[f32], rate: f32) {
        for (w, &t) in weights.iter_mut().zip(target) {
            *w += rate * (t - *w);
        }
    }

    /// Step 5: habituate and move b, refresh b–s, age b's other edges (controlled removal), move
    /// and habituate b's neighbours.
    fn update(&mut self, b: usize, s: usize, rate_b: f32, rate_n: f32) {
        let stride = self.stride();
        self.habituate(b, self.params.tau_b);
        let h_b = self.habituation[b];
        Self::move_towards(
            &mut self.weights[b * stride..(b + 1) * stride],
            &self.train_ctx.global,
            rate_b * h_b,
        );
        self.sync_prefix(b);
        self.connect(b, s);
        self.age_edges(b, s);
        for i in 0..self.edges[b].len() {
            let nb = self.edges[b][i].to as usize;
            let h_n = self.habituation[nb];
            Self::move_towards(
                &mut self.weights[nb * stride..(nb + 1) * stride],
                &self.train_ctx.global,
                rate_n * h_n,
            );
            self.sync_prefix(nb);
            self.habituate(nb, self.params.tau_n);
        }
    }

    /// Ages every edge of b except b–s by 1; an edge older than max_age is removed if N_T ≥ 1 or
    /// its far node is poorly habituated (h > N_T), else kept with age 0 (step 7).
    fn age_edges(&mut self, b: usize, s: usize) {
        let max_age = self.params.max_age;
        let n_t = self.params.removal_threshold;
        let mut i = 0;
        while i < self.edges[b].len() {
            let e = self.edges[b][i];
            let to = e.to as usize;
            if to == s {
                i += 1;
                continue;
            }
            let age = e.age.saturating_add(1);
            if age > max_age {
                if n_t >= 1.0 || self.habituation[to] > n_t {
                    self.disconnect(b, to);
                    continue; // the list shrank: same i is the next edge
                }
                self.set_age(b, to, 0);
            } else {
                self.set_age(b, to, age);
            }
            i += 1;
        }
    }

    fn set_age(&mut self, i: usize, j: usize, age: u32) {
        for (a, z) in [(i, j), (j, i)] {
            if let Some(e) = self.edges[a].iter_mut().find(|e| e.to as usize == z) {
                e.age = age;
            }
        }
    }

    /// Creates edge i–j with age 0, or refreshes its age to 0.
    pub(crate) fn connect(&mut self, i: usize, j: usize) {
        debug_assert_ne!(i, j);
        if self.edge_age(i, j).is_some() {
            self.set_age(i, j, 0);
        } else {
            self.edges[i].push(Edge {
                to: j as u32,
                age: 0,
            });
            self.edges[j].push(Edge {
                to: i as u32,
                age: 0,
            });
        }
    }

    fn disconnect(&mut self, i: usize, j: usize) {
        self.edges[i].retain(|e| e.to as usize != j);
        self.edges[j].retain(|e| e.to as usize != i);
    }

    /// Appends a node whose block is the current global context.
    fn push_node_from_global(&mut self, labels: &[Option<u32>]) -> usize {
        let r = self.len();
        self.weights.extend_from_slice(&self.train_ctx.global);
        self.finish_push(labels);
        r
    }

    /// Refreshes node `j`'s search caches (prefix copy and summary) from its weights.
    fn sync_prefix(&mut self, j: usize) {
        let (p, s) = (metric::prefix_len(self.dim), self.stride());
        let sl = metric::summary_len(self.dim, self.depth);
        let node = &self.weights[j * s..(j + 1) * s];
        self.prefix[j * p..(j + 1) * p].copy_from_slice(&node[..p]);
        metric::summarise(node, self.dim, &mut self.summary[j * sl..(j + 1) * sl]);
    }

    /// Recomputes the search caches (prefix copies and summaries) of every node from `weights`.
    pub(crate) fn rebuild_prefix(&mut self) {
        let (p, s) = (metric::prefix_len(self.dim), self.stride());
        let sl = metric::summary_len(self.dim, self.depth);
        self.prefix.clear();
        for node in self.weights.chunks_exact(s) {
            self.prefix.extend_from_slice(&node[..p]);
        }
        self.summary.clear();
        self.summary.resize(self.weights.len() / s * sl, 0.0);
        for (node, out) in self
            .weights
            .chunks_exact(s)
            .zip(self.summary.chunks_exact_mut(sl))
        {
            metric::summarise(node, self.dim, out);
        }
    }

    /// Completes a node whose block was just appended to `weights`.
    fn finish_push(&mut self, labels: &[Option<u32>]) {
        let (p, r) = (metric::prefix_len(self.dim), self.habituation.len());
        let sl = metric::summary_len(self.dim, self.depth);
        self.prefix.resize((r + 1) * p, 0.0);
        self.summary.resize((r + 1) * sl, 0.0);
        self.sync_prefix(r);
        self.habituation.push(1.0);
        self.edges.push(Vec::new());
        self.synapses.push(Vec::new());
        let inc = self.params.label_increment;
        for (level, hists) in self.labels.iter_mut().enumerate() {
            hists.push(Histogram::start(labels.get(level).copied().flatten(), inc));
        }
    }

    /// Step 4: new node r between b and the input; edges b–r and s–r; b–s removed.
    fn insert(&mut self, b: usize, s: usize, labels: &[Option<u32>]) -> usize {
        let stride = self.stride();
        let r = self.len();
        self.weights
            .extend_from_within(b * stride..(b + 1) * stride);
        for (w, &g) in self.weights[r * stride..]
            .iter_mut()
            .zip(&self.train_ctx.global)
        {
            *w = 0.5 * (*w + g);
        }
        self.finish_push(labels);
        self.connect(b, r);
        self.connect(s, r);
        self.disconnect(b, s);
        r
    }

    /// Step 6: P(prev → cur) += 1 (not for self-transitions); prev ← cur.
    fn link_temporal(&mut self, cur: usize) {
        if let Some(prev) = self.train_ctx.prev_node {
            let prev = prev as usize;
            if prev != cur {
                let list = &mut self.synapses[prev];
                match list.binary_search_by_key(&(cur as u32), |e| e.0) {
                    Ok(at) => list[at].1 = list[at].1.saturating_add(1),
                    Err(at) => list.insert(at, (cur as u32, 1)),
                }
            }
        }
        self.train_ctx.prev_node = Some(cur as u32);
    }

    /// Prediction step: the best node for `x` given the stream state `ctx` (which it advances),
    /// using the same context recursion as training. `no_context` uses K = 0 (input only).
    pub(crate) fn predict_step(
        &self,
        ctx: &mut ContextState,
        x: &[f32],
        no_context: bool,
    ) -> Option<(usize, f32)> {
        let mut seeds = std::mem::take(&mut ctx.seeds);
        self.fill_seeds([ctx.prev_best, None, None], &mut seeds);
        let found = if no_context {
            metric::search(
                self.metric,
                self.inv_var(),
                &self.buffer(),
                x,
                &NO_CONTEXT_ALPHAS,
                false,
                &seeds,
            )
        } else {
            ctx.compute_global(x, self.params.beta, self.dim, self.depth);
            metric::search(
                self.metric,
                self.inv_var(),
                &self.buffer(),
                &ctx.global,
                &self.alphas,
                false,
                &seeds,
            )
        };
        ctx.seeds = seeds;
        let (b, d) = found?.best;
        ctx.prev_best = Some(b as u32);
        if !no_context {
            ctx.prev_block.copy_from_slice(self.node_block(b));
        }
        Some((b, d))
    }

    /// A fresh prediction stream state for this network.
    pub(crate) fn new_context(&self) -> ContextState {
        ContextState::new(self.dim, self.depth)
    }

    /// Removes nodes without edges (ascending index), never going below 2 nodes. Remaining nodes
    /// are renumbered in order; edges and synapses are remapped, synapses to removed nodes
    /// dropped. Returns how many nodes were removed.
    pub fn remove_isolated_nodes(&mut self) -> usize {
        let n = self.len();
        if n <= 2 {
            return 0;
        }
        let mut keep = vec![true; n];
        let mut remaining = n;
        for (j, k) in keep.iter_mut().enumerate() {
            if remaining <= 2 {
                break;
            }
            if self.edges[j].is_empty() {
                *k = false;
                remaining -= 1;
            }
        }
        if remaining == n {
            return 0;
        }
        let mut remap = vec![u32::MAX; n];
        let mut next = 0u32;
        for (j, &k) in keep.iter().enumerate() {
            if k {
                remap[j] = next;
                next += 1;
            }
        }
        let stride = self.stride();
        for (j, &to) in remap.iter().enumerate() {
            if to != u32::MAX && to as usize != j {
                let to = to as usize;
                self.weights
                    .copy_within(j * stride..(j + 1) * stride, to * stride);
            }
        }
        self.weights.truncate(remaining * stride);
        self.rebuild_prefix();
        let kept = |j: usize| keep[j];
        let mut idx = 0;
        self.habituation.retain(|_| {
            idx += 1;
            kept(idx - 1)
        });
        let edges = std::mem::take(&mut self.edges);
        self.edges = edges
            .into_iter()
            .enumerate()
            .filter(|(j, _)| kept(*j))
            .map(|(_, list)| {
                list.into_iter()
                    .filter(|e| remap[e.to as usize] != u32::MAX)
                    .map(|e| Edge {
                        to: remap[e.to as usize],
                        age: e.age,
                    })
                    .collect()
            })
            .collect();
        let synapses = std::mem::take(&mut self.synapses);
        self.synapses = synapses
            .into_iter()
            .enumerate()
            .filter(|(j, _)| kept(*j))
            .map(|(_, list)| {
                list.into_iter()
                    .filter(|e| remap[e.0 as usize] != u32::MAX)
                    .map(|(to, c)| (remap[to as usize], c))
                    .collect()
            })
            .collect();
        for level in &mut self.labels {
            let hists = std::mem::take(level);
            *level = hists
                .into_iter()
                .enumerate()
                .filter(|(j, _)| kept(*j))
                .map(|(_, h)| h)
                .collect();
        }
        self.train_ctx.prev_best = None;
        self.train_ctx.prev_node = self.train_ctx.prev_node.and_then(|p| {
            let m = remap[p as usize];
            (m != u32::MAX).then_some(m)
        });
        n - remaining
    }

    /// Checks every structural invariant: buffer lengths agree; edges in range, not self, not
    /// duplicated, symmetric with equal ages; synapses in range, sorted, positive, not self;
    /// histograms sorted with finite counts > 0; habituation in (0, 1]; weights finite.
    pub fn check_consistency(&self) -> Result<(), String> {
        let n = self.len();
        let stride = self.stride();
        if self.weights.len() != n * stride {
            return Err(format!(
                "weight buffer holds {} floats, {n} nodes need {}",
                self.weights.len(),
                n * stride
            ));
        }
        if self.edges.len() != n || self.synapses.len() != n {
            return Err("edge or synapse lists do not match the node count".into());
        }
        if self.labels.iter().any(|l| l.len() != n) {
            return Err("label histograms do not match the node count".into());
        }
        let p = metric::prefix_len(self.dim);
        let prefix_ok = self.prefix.len() == n * p
            && (0..n).all(|j| {
                self.prefix[j * p..(j + 1) * p] == self.weights[j * stride..j * stride + p]
            });
        if !prefix_ok {
            return Err("search prefix out of sync with the weights".into());
        }
        let sl = metric::summary_len(self.dim, self.depth);
        let mut fresh = vec![0.0; sl];
        let summary_ok = self.summary.len() == n * sl
            && (0..n).all(|j| {
                metric::summarise(self.node_block(j), self.dim, &mut fresh);
                self.summary[j * sl..(j + 1) * sl] == fresh[..]
            });
        if !summary_ok {
            return Err("search summary out of sync with the weights".into());
        }
        if let Some(j) = self.weights.iter().position(|w| !w.is_finite()) {
            return Err(format!("non-finite weight at float {j}"));
        }
        for (j, &h) in self.habituation.iter().enumerate() {
            if !(h > 0.0 && h <= 1.0) {
                return Err(format!("node {j}: habituation {h} not in (0, 1]"));
            }
        }
        for (i, list) in self.edges.iter().enumerate() {
            for (at, e) in list.iter().enumerate() {
                let j = e.to as usize;
                if j >= n {
                    return Err(format!("edge {i}–{j}: dangling (only {n} nodes)"));
                }
                if j == i {
                    return Err(format!("self edge at node {i}"));
                }
                if list[..at].iter().any(|o| o.to == e.to) {
                    return Err(format!("duplicate edge {i}–{j}"));
                }
                match self.edges[j].iter().find(|o| o.to as usize == i) {
                    Some(o) if o.age == e.age => {}
                    Some(o) => {
                        return Err(format!("edge {i}–{j}: ages {} ≠ {}", e.age, o.age));
                    }
                    None => return Err(format!("edge {i}–{j} is not symmetric")),
                }
            }
        }
        for (i, list) in self.synapses.iter().enumerate() {
            for (at, &(to, c)) in list.iter().enumerate() {
                if to as usize >= n {
                    return Err(format!("synapse {i}→{to}: dangling (only {n} nodes)"));
                }
                if to as usize == i || c == 0 {
                    return Err(format!("synapse {i}→{to}: self or zero count"));
                }
                if at > 0 && list[at - 1].0 >= to {
                    return Err(format!("synapses of node {i} not sorted"));
                }
            }
        }
        for (level, hists) in self.labels.iter().enumerate() {
            for (j, h) in hists.iter().enumerate() {
                for (at, &(l, v)) in h.entries.iter().enumerate() {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(format!("node {j} level {level}: count {v} for label {l}"));
                    }
                    if at > 0 && h.entries[at - 1].0 >= l {
                        return Err(format!("node {j} level {level}: histogram not sorted"));
                    }
                }
            }
        }
        if let Some(p) = self.train_ctx.prev_node
            && p as usize >= n
        {
            return Err(format!("previous node {p} out of range"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(k: usize) -> MemoryParams {
        MemoryParams {
            context_depth: k,
            ..MemoryParams::default()
        }
    }

    /// A K = 0, D = 1 network built by hand: nodes (weight, habituation), edges (i, j, age).
    fn manual(p: MemoryParams, nodes: &[(f32, f32)], edges: &[(usize, usize, u32)]) -> GammaGwr {
        let mut net = GammaGwr::new(p, Metric::Manhattan, 1, 1).unwrap();
        for &(w, h) in nodes {
            net.weights.push(w);
            net.finish_push(&[None]);
            *net.habituation.last_mut().unwrap() = h;
        }
        for &(i, j, age) in edges {
            net.connect(i, j);
            net.set_age(i, j, age);
        }
        net.check_consistency().unwrap();
        net
    }

    #[test]
    fn habituation_converges_to_one_minus_inverse_kappa() {
        let p = params(0);
        let kappa = p.kappa;
        let mut net = manual(p, &[(0.0, 1.0), (1.0, 1.0)], &[(0, 1, 0)]);
        let mut last = 1.0;
        for _ in 0..200 {
            net.step(&[0.0], &[None], Supervision::Unsupervised);
            let h = net.habituation(0);
            assert!(
                h > 0.0 && h <= last,
                "habituation must fall monotonically: {h} after {last}"
            );
            last = h;
        }
        let limit = 1.0 - 1.0 / kappa;
        assert!((last - limit).abs() < 1e-5, "h = {last}, expected {limit}");
        // The neighbour habituates too, more slowly (τ_n < τ_b), towards the same limit.
        assert!(net.habituation(1) < 1.0);
        assert!((net.habituation(1) - limit).abs() < 1e-3);
        // One step from h = 1 with τ_b = 0.3: 1 + 0.3·1.05·0 − 0.3 = 0.7.
        let mut fresh = manual(params(0), &[(0.0, 1.0), (1.0, 1.0)], &[(0, 1, 0)]);
        fresh.step(&[0.0], &[None], Supervision::Unsupervised);
        assert!((fresh.habituation(0) - 0.7).abs() < 1e-6);
        assert!((fresh.habituation(1) - 0.9).abs() < 1e-6);
    }

    #[test]
    fn first_two_samples_become_the_first_two_nodes() {
        let mut net = GammaGwr::new(params(1), Metric::Manhattan, 2, 2).unwrap();
        let a = net.step(&[1.0, 2.0], &[Some(4), None], Supervision::Unsupervised);
        assert_eq!((a.node, a.inserted, a.best), (0, true, None));
        let b = net.step(&[3.0, 4.0], &[Some(5), Some(9)], Supervision::Unsupervised);
        assert_eq!((b.node, b.inserted, b.best), (1, true, None));
        assert_eq!(net.weight(0), &[1.0, 2.0]);
        assert_eq!(net.weight(1), &[3.0, 4.0]);
        assert_eq!(net.context(0, 1), &[0.0, 0.0]);
        // C_1 = β·c_{0,1} + (1 − β)·w_0 = 0.6·(1, 2)
        assert!((net.context(1, 1)[0] - 0.6).abs() < 1e-6);
        assert!((net.context(1, 1)[1] - 1.2).abs() < 1e-6);
        assert_eq!(net.edge_age(0, 1), Some(0));
        assert_eq!(net.synapse(0, 1), 1);
        assert_eq!(net.label(0, 0), Some(4));
        assert_eq!(net.label(1, 0), None);
        assert_eq!(net.label(1, 1), Some(9));
        assert_eq!((net.habituation(0), net.habituation(1)), (1.0, 1.0));
    }

    #[test]
    fn insertion_needs_low_activity_low_habituation_and_room() {
        // Far input (a = e^-10 < a_T) but b is not habituated (h = 1 ≥ h_T): update, no insertion.
        let mut net = manual(params(0), &[(0.0, 1.0), (1.0, 1.0)], &[(0, 1, 0)]);
        let out = net.step(&[-10.0], &[Some(3)], Supervision::Unsupervised);
        assert!(!out.inserted);
        assert_eq!(net.len(), 2);

        // Habituated b (h = 0.05 < h_T) and far input: insertion between b and x.
        let mut net = manual(params(0), &[(0.0, 0.05), (1.0, 1.0)], &[(0, 1, 0)]);
        let out = net.step(&[-10.0], &[Some(3)], Supervision::Unsupervised);
        assert!(out.inserted);
        assert_eq!(out.best.unwrap().0, 0);
        assert_eq!(out.node, 2);
        assert_eq!(net.weight(2), &[-5.0]);
        assert_eq!(net.habituation(2), 1.0);
        assert_eq!(net.label(0, 2), Some(3));
        assert_eq!(net.histogram(0, 2).get(3), 1.0);
        assert_eq!(net.edge_age(0, 2), Some(0));
        assert_eq!(net.edge_age(1, 2), Some(0));
        assert_eq!(net.edge_age(0, 1), None, "b–s is removed on insertion");
        assert_eq!(net.weight(0), &[0.0], "b is not moved on insertion");
        net.check_consistency().unwrap();

        // Habituated b but near input (a = e^-0.1 ≥ a_T = 0.5): update.
        let mut net = manual(params(0), &[(0.0, 0.05), (1.0, 1.0)], &[(0, 1, 0)]);
        assert!(
            !net.step(&[0.1], &[None], Supervision::Unsupervised)
                .inserted
        );

        // Threshold is strict: a just above a_T does not insert, just below does.
        let a_t = 0.5f32;
        let d = -(a_t.ln());
        for (x, inserts) in [(d * 0.999, false), (d * 1.001, true)] {
            let mut net = manual(params(0), &[(0.0, 0.05), (5.0, 1.0)], &[(0, 1, 0)]);
            let out = net.step(&[-x], &[None], Supervision::Unsupervised);
            assert_eq!(out.inserted, inserts, "x = {x}");
        }

        // Capacity: no insertion at max_nodes.
        let capped = MemoryParams {
            max_nodes: Some(2),
            ..params(0)
        };
        let mut net = manual(capped, &[(0.0, 0.05), (1.0, 1.0)], &[(0, 1, 0)]);
        assert!(
            !net.step(&[-10.0], &[None], Supervision::Unsupervised)
                .inserted
        );
        assert_eq!(net.len(), 2);
    }

    #[test]
    fn update_moves_b_and_neighbours_by_their_rates() {
        let p = params(0);
        let (eb, en) = (p.epsilon_b, p.epsilon_n);
        let mut net = manual(
            p,
            &[(0.0, 1.0), (1.0, 1.0), (2.0, 1.0)],
            &[(0, 1, 0), (0, 2, 0)],
        );
        net.step(&[-0.5], &[None], Supervision::Unsupervised);
        // b = 0: h 1 → 0.7, then w += ε_b·0.7·(−0.5 − 0).
        assert!((net.weight(0)[0] - eb * 0.7 * -0.5).abs() < 1e-6);
        // neighbours move with their own (pre-habituation) h = 1.
        assert!((net.weight(1)[0] - (1.0 + en * (-0.5 - 1.0))).abs() < 1e-6);
        assert!((net.weight(2)[0] - (2.0 + en * (-0.5 - 2.0))).abs() < 1e-6);
    }

    /// Ages of edges 0–1, 0–2, 0–3 (`None`: no edge).
    type EdgeAges = (Option<u32>, Option<u32>, Option<u32>);

    /// b = node 0 fires max_age + 1 times with s = node 1; node 2 is a well-trained neighbour
    /// (h ≤ N_T), node 3 a poorly trained one (h > N_T).
    fn aging_run(removal_threshold: f32) -> (GammaGwr, Vec<EdgeAges>) {
        let p = MemoryParams {
            max_age: 3,
            removal_threshold,
            ..params(0)
        };
        let mut net = manual(
            p,
            &[(0.0, 1.0), (0.1, 1.0), (5.0, 0.05), (-5.0, 1.0)],
            &[(0, 2, 0), (0, 3, 0)],
        );
        let mut ages = Vec::new();
        for _ in 0..5 {
            let out = net.step(&[0.0], &[None], Supervision::Unsupervised);
            assert_eq!(out.best.unwrap().0, 0);
            net.check_consistency().unwrap();
            ages.push((net.edge_age(0, 1), net.edge_age(0, 2), net.edge_age(0, 3)));
        }
        (net, ages)
    }

    #[test]
    fn edges_are_created_aged_per_node_and_removed_plain_gwr_with_nt_one() {
        let (net, ages) = aging_run(1.0);
        // b–s created at step 1 and refreshed every step; the other edges age by 1 per firing
        // of b and go when they pass max_age = 3.
        assert_eq!(ages[0], (Some(0), Some(1), Some(1)));
        assert_eq!(ages[2], (Some(0), Some(3), Some(3)));
        assert_eq!(ages[3], (Some(0), None, None));
        assert_eq!(ages[4], (Some(0), None, None));
        assert!(net.edges(2).is_empty() && net.edges(3).is_empty());
    }

    #[test]
    fn controlled_removal_keeps_edges_of_well_trained_nodes() {
        let (net, ages) = aging_run(0.2);
        assert_eq!(ages[2], (Some(0), Some(3), Some(3)));
        // Past max_age: the edge to the well-trained node 2 is kept with age 0, the edge to the
        // poorly trained node 3 (h ≈ 0.66 > N_T) is removed.
        assert!(net.habituation(2) <= 0.2 && net.habituation(3) > 0.2);
        assert_eq!(ages[3], (Some(0), Some(0), None));
        assert_eq!(ages[4], (Some(0), Some(1), None));
    }

    #[test]
    fn edges_of_nodes_that_do_not_fire_do_not_age() {
        let mut net = manual(
            params(0),
            &[(0.0, 1.0), (0.1, 1.0), (5.0, 1.0), (5.1, 1.0)],
            &[(2, 3, 7)],
        );
        for _ in 0..10 {
            net.step(&[0.0], &[None], Supervision::Unsupervised);
        }
        assert_eq!(net.edge_age(2, 3), Some(7));
    }

    #[test]
    fn isolated_node_removal_remaps_edges_synapses_labels_and_state() {
        let mut net = manual(
            params(0),
            &[
                (0.0, 1.0),
                (1.0, 0.9),
                (2.0, 0.8),
                (3.0, 0.7),
                (4.0, 0.6),
                (5.0, 0.5),
            ],
            &[(0, 2, 1), (2, 4, 2), (4, 5, 3)],
        );
        for (j, l) in [(0, 10), (1, 11), (2, 12), (3, 13), (4, 14), (5, 15)] {
            net.labels[0][j] = Histogram::start(Some(l), 1.0);
        }
        for (i, j, c) in [(0, 1, 4), (0, 2, 1), (2, 4, 2), (3, 5, 9), (5, 0, 3)] {
            net.synapses[i].push((j, c));
        }
        net.train_ctx.prev_node = Some(4);
        net.check_consistency().unwrap();

        assert_eq!(net.remove_isolated_nodes(), 2);
        net.check_consistency().unwrap();
        assert_eq!(net.len(), 4);
        // Survivors 0, 2, 4, 5 become 0, 1, 2, 3 with their data.
        assert_eq!(net.weights, vec![0.0, 2.0, 4.0, 5.0]);
        assert_eq!(net.habituation, vec![1.0, 0.8, 0.6, 0.5]);
        let labels: Vec<_> = (0..4).map(|j| net.label(0, j).unwrap()).collect();
        assert_eq!(labels, vec![10, 12, 14, 15]);
        assert_eq!(net.edge_age(0, 1), Some(1));
        assert_eq!(net.edge_age(1, 2), Some(2));
        assert_eq!(net.edge_age(2, 3), Some(3));
        assert_eq!(net.edge_count(), 3);
        // 0→1 (to a removed node) and 3→5 (from one) are gone; the rest is remapped.
        assert_eq!(net.synapses(0), &[(1, 1)]);
        assert_eq!(net.synapses(1), &[(2, 2)]);
        assert_eq!(net.synapses(2), &[]);
        assert_eq!(net.synapses(3), &[(0, 3)]);
        assert_eq!(net.train_ctx.prev_node, Some(2));
        assert_eq!(net.remove_isolated_nodes(), 0);
    }

    #[test]
    fn isolated_node_removal_never_goes_below_two_nodes() {
        let mut net = manual(params(0), &[(0.0, 1.0), (1.0, 1.0), (2.0, 1.0)], &[]);
        assert_eq!(net.remove_isolated_nodes(), 1);
        assert_eq!(net.len(), 2);
        assert_eq!(net.weights, vec![1.0, 2.0]);
        assert_eq!(net.remove_isolated_nodes(), 0);
        assert_eq!(net.len(), 2);
    }

    #[test]
    fn global_context_recursion_and_reset() {
        let (dim, depth, beta) = (2, 3, 0.4f32);
        let mut ctx = ContextState::new(dim, depth);
        ctx.compute_global(&[1.0, 2.0], beta, dim, depth);
        assert_eq!(ctx.global, vec![1.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
        // previous best block [w, c1, c2]
        ctx.prev_block = vec![10.0, 20.0, 1.0, 2.0, 3.0, 5.0];
        ctx.compute_global(&[7.0, 8.0], beta, dim, depth);
        // C1 = β·c1 + (1−β)·w; C2 = β·c2 + (1−β)·c1
        let want = [
            7.0,
            8.0,
            0.4 * 1.0 + 0.6 * 10.0,
            0.4 * 2.0 + 0.6 * 20.0,
            0.4 * 3.0 + 0.6 * 1.0,
            0.4 * 5.0 + 0.6 * 2.0,
        ];
        for (g, w) in ctx.global.iter().zip(want) {
            assert!((g - w).abs() < 1e-5, "{:?} vs {want:?}", ctx.global);
        }
        ctx.prev_node = Some(3);
        ctx.reset();
        assert_eq!(ctx.prev_node, None);
        ctx.compute_global(&[7.0, 8.0], beta, dim, depth);
        assert_eq!(ctx.global, vec![7.0, 8.0, 0.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn training_and_prediction_use_the_same_recursion() {
        // Frozen learning (ε = 0, a_T = 0): training steps must pick the nodes prediction picks.
        let p = MemoryParams {
            epsilon_b: 0.0,
            epsilon_n: 0.0,
            activation_threshold: 0.0,
            ..params(2)
        };
        let mut net = GammaGwr::new(p, Metric::Manhattan, 2, 1).unwrap();
        // Build a few nodes with learning on, then freeze.
        let mut learn = net.clone();
        learn.params.activation_threshold = 0.99;
        learn.params.habituation_threshold = 1.0;
        learn.params.epsilon_b = 0.5;
        let stream: Vec<[f32; 2]> = (0..30)
            .map(|t| [((t * 7) % 11) as f32 * 0.3, ((t * 5) % 13) as f32 * 0.2])
            .collect();
        for x in &stream {
            learn.step(x, &[None], Supervision::Unsupervised);
        }
        assert!(learn.len() > 5);
        net.weights = learn.weights.clone();
        net.rebuild_prefix();
        net.habituation = learn.habituation.clone();
        net.edges = learn.edges.clone();
        net.synapses = learn.synapses.clone();
        net.labels = learn.labels.clone();
        net.begin_sequence();
        let mut ctx = net.new_context();
        let mut contexts_mattered = false;
        for x in &stream {
            let predicted = net.predict_step(&mut ctx, x, false).unwrap();
            let no_ctx = net.predict_step(&mut net.new_context(), x, true).unwrap();
            contexts_mattered |= predicted.0 != no_ctx.0;
            let trained = net.step(x, &[None], Supervision::Unsupervised);
            assert!(!trained.inserted);
            let (b, d) = trained.best.unwrap();
            assert_eq!(b, predicted.0);
            assert!((d - predicted.1).abs() < 1e-5);
        }
        assert!(
            contexts_mattered,
            "the stream should exercise the temporal context"
        );
    }

    #[test]
    fn temporal_synapses_follow_the_stream_within_sequences() {
        let mut net = manual(
            params(0),
            &[(0.0, 1.0), (10.0, 1.0), (20.0, 1.0)],
            &[(0, 1, 0), (1, 2, 0)],
        );
        for x in [0.0, 10.0, 10.0, 20.0] {
            net.step(&[x], &[None], Supervision::Unsupervised);
        }
        assert_eq!(net.synapse(0, 1), 1);
        assert_eq!(net.synapse(1, 1), 0, "no self-synapse");
        assert_eq!(net.synapse(1, 2), 1);
        net.begin_sequence();
        net.step(&[0.0], &[None], Supervision::Unsupervised);
        assert_eq!(
            net.synapse(2, 0),
            0,
            "no synapse across a sequence boundary"
        );
        net.step(&[20.0], &[None], Supervision::Unsupervised);
        net.step(&[10.0], &[None], Supervision::Unsupervised);
        net.step(&[20.0], &[None], Supervision::Unsupervised);
        net.step(&[10.0], &[None], Supervision::Unsupervised);
        assert_eq!(net.synapse(0, 2), 1);
        assert_eq!(net.synapse(2, 1), 2);
        assert_eq!(net.successor(1), Some(2));
        assert_eq!(net.successor(2), Some(1));
        net.check_consistency().unwrap();
    }

    #[test]
    fn label_histograms_are_open_ended_and_floored() {
        let mut h = Histogram::default();
        assert_eq!(h.argmax(), None);
        h.reinforce(4_000_000_000, 1.0, 0.1);
        h.reinforce(7, 1.0, 0.1);
        assert_eq!(h.entries(), &[(7, 1.0), (4_000_000_000, 0.9)]);
        assert_eq!(h.argmax(), Some(7));
        for _ in 0..9 {
            h.reinforce(7, 1.0, 0.1);
        }
        // 0.9 − 9·0.1 = 0 → dropped
        assert_eq!(h.entries().len(), 1);
        assert_eq!(h.get(7), 10.0);
        assert_eq!(h.get(4_000_000_000), 0.0);
        let mut tie = Histogram::from_entries(vec![(3, 2.0), (9, 2.0)]);
        assert_eq!(tie.argmax(), Some(3));
        tie.reinforce(9, 1.0, 0.0);
        assert_eq!(tie.argmax(), Some(9));
    }

    #[test]
    fn unlabelled_samples_update_weights_but_not_histograms() {
        let mut net = manual(params(0), &[(0.0, 1.0), (1.0, 1.0)], &[(0, 1, 0)]);
        net.labels[0][0] = Histogram::start(Some(2), 1.0);
        net.step(&[0.2], &[None], Supervision::Unsupervised);
        assert_eq!(net.histogram(0, 0).entries(), &[(2, 1.0)]);
        assert!(net.weight(0)[0] > 0.0);
        net.step(&[0.2], &[Some(5)], Supervision::Unsupervised);
        assert_eq!(net.histogram(0, 0).entries(), &[(2, 0.9), (5, 1.0)]);
    }

    #[test]
    fn regulated_growth_follows_the_ground_truth() {
        let p = params(0);
        let (eb, mr) = (p.epsilon_b, p.mod_rate);
        let labelled = |h0: f32| {
            let mut net = manual(p.clone(), &[(0.0, h0), (1.0, 1.0)], &[(0, 1, 0)]);
            net.labels[0][0] = Histogram::start(Some(1), 1.0);
            net
        };
        // Right prediction, far input, habituated: no insertion, normal update with labels.
        let mut net = labelled(0.05);
        let out = net.step(&[-10.0], &[Some(1)], Supervision::Regulated);
        assert!(!out.inserted);
        assert_eq!(net.histogram(0, 0).get(1), 2.0);
        // Wrong prediction, far input, habituated: insertion with the true label.
        let mut net = labelled(0.05);
        let out = net.step(&[-10.0], &[Some(2)], Supervision::Regulated);
        assert!(out.inserted);
        assert_eq!(net.label(0, out.node), Some(2));
        // Wrong prediction, not insertable (h = 1): update at ε·mod_rate, no label update.
        let mut net = labelled(1.0);
        let out = net.step(&[-10.0], &[Some(2)], Supervision::Regulated);
        assert!(!out.inserted);
        assert_eq!(net.histogram(0, 0).entries(), &[(1, 1.0)]);
        let moved = net.weight(0)[0];
        assert!((moved - eb * mr * 0.7 * -10.0).abs() < 1e-6, "{moved}");
        // No ground truth: normal update, no insertion, no label change.
        let mut net = labelled(0.05);
        let out = net.step(&[-10.0], &[None], Supervision::Regulated);
        assert!(!out.inserted);
        assert_eq!(net.histogram(0, 0).entries(), &[(1, 1.0)]);
    }
}
