//! Intrinsic replay: recursively reactivated neural activation trajectories (RNATs).
//!
//! For every episodic node i, the chain i → argmax_j P(i→j) → … follows the temporal synapses
//! for up to `chain_length` nodes (default K+1), stopping early at a node without successor.
//! Each chain is snapshotted (weights and label argmaxes) from the network as it is before
//! replay, then replayed as a short sequence of its own: to the episodic memory with the nodes'
//! instance and category labels, and to the semantic memory (input = the same node weights,
//! regulated by the category labels). No stored samples are needed.
//!
//! By default (`replay.budget = "all"`, the paper's) every episodic node starts a chain, so a
//! replay costs about (K+1) × nodes training steps whatever the episode learnt: on the paper
//! preset most of a run's time. With a budget of b pseudo-samples per sample learnt
//! ([`ReplayBudget::Learnt`]), a replay starts chains at nodes drawn without replacement with
//! the config's seed until ⌈b × samples trained since the last replay⌉ pseudo-samples are
//! replayed (the last chain whole), or every node has had its chain.
//!
//! ```
//! use lgdm_gdm::{Gdm, GdmConfig, Sample};
//! let mut gdm = Gdm::new(GdmConfig::default(), 1).unwrap();
//! let xs: Vec<[f32; 1]> = (0..20).map(|i| [i as f32]).collect();
//! let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, 0, 0, 0)).collect();
//! gdm.train(&samples).unwrap();
//! let before = gdm.episodic().len();
//! let stats = gdm.replay().unwrap();
//! assert_eq!(stats.chains, before);
//! assert!(stats.samples >= before);
//! ```

use lgdm_base::seed::splitmix64;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use crate::config::ReplayBudget;
use crate::dual::Gdm;
use crate::error::GdmError;
use crate::memory::{CATEGORY_LEVEL, INSTANCE_LEVEL};
use crate::network::GammaGwr;

/// Summary of one [`Gdm::replay`] call.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct ReplayStats {
    /// Chains replayed (one per episodic node that existed when replay started, unless a
    /// [`ReplayBudget::Learnt`] budget ran out first).
    pub chains: usize,
    /// Pseudo-samples replayed (sum of chain lengths).
    pub samples: usize,
}

/// The RNAT of every node of `net`, in node order: `chains[i]` starts at node i and follows
/// the strongest outgoing synapse for at most `length` nodes.
pub fn rnats(net: &GammaGwr, length: usize) -> Vec<Vec<usize>> {
    (0..net.len())
        .map(|i| {
            let mut chain = Vec::new();
            walk(|j| net.successor(j), i, length, &mut chain);
            chain
        })
        .collect()
}

/// Fills `chain` with the RNAT from `start`: `start`, then `successor` of the last node, for at
/// most `length` nodes, stopping at a node without successor.
fn walk(
    successor: impl Fn(usize) -> Option<usize>,
    start: usize,
    length: usize,
    chain: &mut Vec<usize>,
) {
    chain.clear();
    let mut cur = start;
    chain.push(cur);
    while chain.len() < length {
        match successor(cur) {
            Some(next) => {
                chain.push(next);
                cur = next;
            }
            None => break,
        }
    }
}

impl Gdm {
    /// Intrinsic replay of RNATs into both memories (call after an episode, typically after
    /// [`Gdm::end_episode`]). With `replay.shuffle`, or under a [`ReplayBudget::Learnt`]
    /// budget, the chains are replayed in an order drawn from the config's seed and the number
    /// of earlier replays; the budget (`replay.budget`) says how many. The next training sample
    /// starts a new sequence.
    pub fn replay(&mut self) -> Result<ReplayStats, GdmError> {
        let learnt = std::mem::take(&mut self.learnt);
        let em = &self.episodic.net;
        if em.len() < 2 {
            return Ok(ReplayStats::default());
        }
        let budgeted = matches!(self.config.replay.budget, ReplayBudget::Learnt(_));
        let budget = match self.config.replay.budget {
            ReplayBudget::All => usize::MAX,
            // Validated: finite, > 0 and bounded; the product saturates in the cast.
            ReplayBudget::Learnt(b) => (b as f64 * learnt as f64).ceil() as usize,
        };
        let dim = self.dim;
        let n = em.len();
        let length = self.config.replay_chain_length();
        // Snapshot before any replay step changes the network: per node its input weight,
        // labels and successor (O(nodes · D), whatever the chain length; the chains are walked
        // on the snapshot as they are replayed).
        let mut weights = Vec::with_capacity(n * dim);
        for j in 0..n {
            weights.extend_from_slice(em.weight(j));
        }
        let labels: Vec<(Option<u32>, Option<u32>)> = (0..n)
            .map(|j| (em.label(INSTANCE_LEVEL, j), em.label(CATEGORY_LEVEL, j)))
            .collect();
        let successors: Vec<Option<usize>> = (0..n).map(|j| em.successor(j)).collect();
        // Speed hints only (results do not depend on them): a pseudo-sample is tried first
        // against the episodic node it came from, and against the semantic node that matched
        // the same episodic node earlier in this replay. Replay removes no nodes, so the
        // indices stay valid.
        let mut semantic_hint: Vec<Option<usize>> = vec![None; n];
        let mut order: Vec<usize> = (0..n).collect();
        if self.config.replay.shuffle || budgeted {
            let seed = splitmix64(self.config.seed ^ splitmix64(self.replays));
            order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        }
        let mut chain = Vec::with_capacity(length.min(n + 1));
        let mut total = 0usize;
        let mut chains = 0usize;
        for &start in &order {
            if total >= budget {
                break;
            }
            chains += 1;
            walk(|j| successors[j], start, length, &mut chain);
            total += chain.len();
            self.begin_sequence();
            for &source in &chain {
                let x = &weights[source * dim..(source + 1) * dim];
                let (instance, category) = labels[source];
                self.episodic.net.hint_next(source);
                self.episodic.train_step(x, instance, category);
                if let Some(h) = semantic_hint[source] {
                    self.semantic.net.hint_next(h);
                }
                if let Some((b, _)) = self.semantic.train_step(x, category).best {
                    semantic_hint[source] = Some(b);
                }
            }
        }
        self.begin_sequence();
        self.sequence = None;
        self.replays = self.replays.wrapping_add(1);
        let stats = ReplayStats {
            chains,
            samples: total,
        };
        tracing::debug!(
            chains = stats.chains,
            samples = stats.samples,
            episodic_nodes = self.episodic.len(),
            semantic_nodes = self.semantic.len(),
            "gdm replay"
        );
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{GdmConfig, MAX_REPLAY_BUDGET};
    use crate::dual::Sample;

    /// 40 two-dimensional views in 4 sequences.
    fn xs() -> Vec<[f32; 2]> {
        (0..40)
            .map(|i| {
                [
                    (i / 10) as f32 * 3.0 + 0.1 * (i % 10) as f32,
                    0.05 * (i % 7) as f32,
                ]
            })
            .collect()
    }

    fn trained(budget: ReplayBudget, seed: u64) -> (Gdm, usize) {
        let mut config = GdmConfig {
            seed,
            ..GdmConfig::paper_batch()
        };
        config.replay.budget = budget;
        let mut gdm = Gdm::new(config, 2).unwrap();
        let xs = xs();
        let samples: Vec<Sample> = xs
            .iter()
            .enumerate()
            .map(|(i, x)| Sample::labelled(x, (i / 10) as u64, (i / 10) as u32, 0))
            .collect();
        for _ in 0..3 {
            gdm.train(&samples).unwrap();
        }
        gdm.end_episode();
        // A later, smaller episode: what the budget is measured against.
        gdm.replay().unwrap();
        gdm.train(&samples[..5]).unwrap();
        let nodes = gdm.episodic().len();
        (gdm, nodes)
    }

    #[test]
    fn a_budget_replays_about_that_many_pseudo_samples_per_sample_learnt() {
        let (mut all, nodes) = trained(ReplayBudget::All, 3);
        assert!(nodes > 10, "{nodes} nodes");
        let stats = all.replay().unwrap();
        assert_eq!(stats.chains, nodes);
        // Nothing learnt since: "all" still replays every chain.
        let now = all.episodic().len();
        assert_eq!(all.replay().unwrap().chains, now);

        let (mut one, _) = trained(ReplayBudget::Learnt(1.0), 3);
        let stats = one.replay().unwrap();
        // 5 samples learnt: chains until 5 pseudo-samples, the last one whole.
        assert!(stats.samples >= 5 && stats.samples < 5 + 3, "{stats:?}");
        assert!(stats.chains < nodes);
        // Nothing learnt since the last replay: nothing to replay.
        assert_eq!(one.replay().unwrap(), ReplayStats::default());

        let (mut half, _) = trained(ReplayBudget::Learnt(0.5), 3);
        let stats = half.replay().unwrap();
        assert!(stats.samples >= 3 && stats.samples < 3 + 3, "{stats:?}");

        // A budget above (K+1) × nodes / learnt replays every chain.
        let (mut big, nodes) = trained(ReplayBudget::Learnt(MAX_REPLAY_BUDGET), 3);
        assert_eq!(big.replay().unwrap().chains, nodes);
    }

    #[test]
    fn budgeted_chains_are_drawn_with_the_seed() {
        let replayed = |seed: u64| {
            let (mut gdm, _) = trained(ReplayBudget::Learnt(1.0), seed);
            gdm.replay().unwrap();
            gdm
        };
        assert_eq!(replayed(3).to_bytes(), replayed(3).to_bytes());
        // Another seed draws other chains (the models differ from the first training on).
        let (mut a, _) = trained(ReplayBudget::Learnt(1.0), 3);
        let (mut b, _) = trained(ReplayBudget::Learnt(1.0), 4);
        let (sa, sb) = (a.replay().unwrap(), b.replay().unwrap());
        assert!(sa.chains > 0 && sb.chains > 0);
        assert_ne!(a.to_bytes(), b.to_bytes());
    }
}
