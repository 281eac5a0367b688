//! The Gamma-GWR network: a growing self-organising network whose nodes carry an input weight,
//! K temporal context vectors, a habituation counter, label histograms, undirected aged edges
//! and directed temporal synapses (DESIGN.md §3, steps 1–7).
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
//!     net.train_step(x, &[Some(i as u32 % 2)], Supervision::Unsupervised);
//! }
//! assert!(net.len() >= 2);
//! net.check_consistency().unwrap();
//! ```

use crate::config::MemoryParams;
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
}

/// Equality ignores the `global` scratch buffer.
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
        }
    }

    /// Starts a new sequence: all contexts zero, no previous node.
    pub fn reset(&mut self) {
        self.prev_block.fill(0.0);
        self.prev_node = None;
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
#[derive(Debug, Clone, PartialEq)]
pub struct GammaGwr {
    pub(crate) params: MemoryParams,
    pub(crate) metric: Metric,
    pub(crate) alphas: Vec<f32>,
    pub(crate) dim: usize,
    pub(crate) depth: usize,
    pub(crate) weights: Vec<f32>,
    pub(crate) habituation: Vec<f32>,
    pub(crate) edges: Vec<Vec<Edge>>,
    pub(crate) synapses: Vec<Vec<(u32, u32)>>,
    /// `labels[level][node]`.
    pub(crate) labels: Vec<Vec<Histogram>>,
    pub(crate) stats: Option<RunningStats>,
    pub(crate) train_ctx: ContextState,
}

const NO_CONTEXT_ALPHAS: [f32; 1] = [1.0];

impl GammaGwr {
    /// An empty network for `dim`-dimensional inputs with `levels` label levels.
    pub fn new(
        params: MemoryParams,
        metric: Metric,
        dim: usize,
        levels: usize,
    ) -> Result<Self, GdmError> {
        if dim == 0 {
            return Err(GdmError::ZeroDimension);
        }
        metric.validate()?;
        params.validate("memory")?;
        if levels == 0 {
            return Err(ConfigError::invalid("levels", "at least one label level").into());
        }
        let depth = params.context_depth + 1;
        Ok(GammaGwr {
            alphas: params.context_weights(),
            metric,
            dim,
            depth,
            weights: Vec::new(),
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
            dim: self.dim,
            depth: self.depth,
        }
    }

    /// Starts a new training sequence: contexts reset to zero, no temporal synapse from the
    /// previous sample.
    pub fn begin_sequence(&mut self) {
        self.train_ctx.reset();
    }

    /// One training step on input `x` (length D, finite) with one optional label per level.
    ///
    /// Panics if `x.len() != dim()` or `labels.len() != levels()`; the dual model validates its
    /// input before calling this.
    pub fn train_step(
        &mut self,
        x: &[f32],
        labels: &[Option<u32>],
        supervision: Supervision,
    ) -> StepOutcome {
        assert_eq!(x.len(), self.dim, "input dimension");
        assert_eq!(labels.len(), self.levels(), "label levels");
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
        let Matches { best, second } = metric::search(
            self.metric,
            self.inv_var(),
            &self.buffer(),
            &self.train_ctx.global,
            &self.alphas,
            true,
        )
        .expect("network has nodes");
        let (b, d_b) = best;
        let s_node = second.expect("network has two nodes").0;
        let stride = self.stride();
        // The context of the next step comes from b as it was matched (before its update).
        self.train_ctx
            .prev_block
            .copy_from_slice(&self.weights[b * stride..(b + 1) * stride]);

        let p = &self.params;
        let activity = (-d_b).exp();
        let truth = labels[0];
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
                for (level, label) in labels.iter().enumerate() {
                    if let Some(y) = *label {
                        self.labels[level][b].reinforce(y, inc, dec);
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

    fn finish_push(&mut self, labels: &[Option<u32>]) {
        self.habituation.push(1.0);
        self.edges.push(Vec::new());
        self.synapses.push(Vec::new());
        let inc = self.params.label_increment;
        for (level, label) in labels.iter().enumerate() {
            self.labels[level].push(Histogram::start(*label, inc));
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
        if no_context {
            let m = metric::search(
                self.metric,
                self.inv_var(),
                &self.buffer(),
                x,
                &NO_CONTEXT_ALPHAS,
                false,
            )?;
            return Some(m.best);
        }
        ctx.compute_global(x, self.params.beta, self.dim, self.depth);
        let m = metric::search(
            self.metric,
            self.inv_var(),
            &self.buffer(),
            &ctx.global,
            &self.alphas,
            false,
        )?;
        let (b, _) = m.best;
        ctx.prev_block.copy_from_slice(self.node_block(b));
        Some(m.best)
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
