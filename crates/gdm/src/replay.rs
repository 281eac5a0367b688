//! Intrinsic replay: recursively reactivated neural activation trajectories (RNATs).
//!
//! For every episodic node i, the chain i → argmax_j P(i→j) → … follows the temporal synapses
//! for up to `chain_length` nodes (default K+1), stopping early at a node without successor.
//! Each chain is snapshotted (weights and label argmaxes) from the network as it is before
//! replay, then replayed as a short sequence of its own: to the episodic memory with the nodes'
//! instance and category labels, and to the semantic memory (input = the same node weights,
//! regulated by the category labels). No stored samples are needed.
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

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use crate::dual::Gdm;
use crate::error::GdmError;
use crate::memory::{CATEGORY_LEVEL, INSTANCE_LEVEL};
use crate::network::GammaGwr;

/// Summary of one [`Gdm::replay`] call.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct ReplayStats {
    /// Chains replayed (one per episodic node that existed when replay started).
    pub chains: usize,
    /// Pseudo-samples replayed (sum of chain lengths).
    pub samples: usize,
}

/// The RNAT of every node of `net`, in node order: `chains[i]` starts at node i and follows
/// the strongest outgoing synapse for at most `length` nodes.
pub fn rnats(net: &GammaGwr, length: usize) -> Vec<Vec<usize>> {
    (0..net.len())
        .map(|i| {
            let mut chain = Vec::with_capacity(length);
            let mut cur = i;
            chain.push(cur);
            while chain.len() < length {
                match net.successor(cur) {
                    Some(next) => {
                        chain.push(next);
                        cur = next;
                    }
                    None => break,
                }
            }
            chain
        })
        .collect()
}

/// splitmix64: decorrelates the per-call seeds.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Gdm {
    /// Intrinsic replay of RNATs into both memories (call after an episode, typically after
    /// [`Gdm::end_episode`]). With `replay.shuffle` the chains are replayed in an order drawn
    /// from the config's seed and the number of earlier replays. The next training sample
    /// starts a new sequence.
    pub fn replay(&mut self) -> Result<ReplayStats, GdmError> {
        let em = &self.episodic.net;
        if em.len() < 2 {
            return Ok(ReplayStats::default());
        }
        let dim = self.dim;
        let chains = rnats(em, self.config.replay_chain_length());
        // Snapshot before any replay step changes the network.
        let total: usize = chains.iter().map(Vec::len).sum();
        let mut weights = Vec::with_capacity(total * dim);
        let mut labels = Vec::with_capacity(total);
        let mut spans = Vec::with_capacity(chains.len());
        let mut sources = Vec::with_capacity(total);
        for chain in &chains {
            let start = labels.len();
            for &j in chain {
                weights.extend_from_slice(em.weight(j));
                labels.push((em.label(INSTANCE_LEVEL, j), em.label(CATEGORY_LEVEL, j)));
                sources.push(j);
            }
            spans.push(start..labels.len());
        }
        // Speed hints only (results do not depend on them): a pseudo-sample is tried first
        // against the episodic node it came from, and against the semantic node that matched
        // the same episodic node earlier in this replay. Replay removes no nodes, so the
        // indices stay valid.
        let mut semantic_hint: Vec<Option<usize>> = vec![None; em.len()];
        if self.config.replay.shuffle {
            let seed = mix(self.config.seed ^ mix(self.replays));
            spans.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        }
        for span in &spans {
            self.begin_sequence();
            for t in span.clone() {
                let x = &weights[t * dim..(t + 1) * dim];
                let (instance, category) = labels[t];
                let source = sources[t];
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
        self.replays += 1;
        let stats = ReplayStats {
            chains: spans.len(),
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
