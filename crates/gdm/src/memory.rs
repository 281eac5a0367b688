//! The two memories of the dual model, each a [`GammaGwr`] with its own training stream state.
//!
//! - [`EpisodicMemory`] (G-EM): unsupervised growth; label levels 0 = instance, 1 = category.
//! - [`SemanticMemory`] (G-SM): one label level (category); its input is the episodic best
//!   node's weight, and its growth is regulated by the ground-truth category.
//!
//! ```
//! use lgdm_gdm::{Gdm, GdmConfig, Sample};
//! let mut gdm = Gdm::new(GdmConfig::default(), 2).unwrap();
//! let xs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
//! let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, 0, 7, 1)).collect();
//! gdm.train(&samples).unwrap();
//! assert!(gdm.episodic().len() >= 2);
//! assert_eq!(gdm.semantic().network().levels(), 1);
//! ```

use crate::config::MemoryParams;
use crate::error::GdmError;
use crate::metric::Metric;
use crate::network::{GammaGwr, StepOutcome, Supervision};

/// Label level of instance labels in the episodic memory.
pub const INSTANCE_LEVEL: usize = 0;
/// Label level of category labels in the episodic memory.
pub const CATEGORY_LEVEL: usize = 1;

/// Episodic memory G-EM: a Gamma-GWR with instance and category histograms, unsupervised growth.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodicMemory {
    pub(crate) net: GammaGwr,
}

impl EpisodicMemory {
    /// An empty episodic memory for `dim`-dimensional inputs.
    pub fn new(params: MemoryParams, metric: Metric, dim: usize) -> Result<Self, GdmError> {
        Ok(EpisodicMemory {
            net: GammaGwr::new(params, metric, dim, 2)?,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.net.len()
    }

    /// True if there is no node yet.
    pub fn is_empty(&self) -> bool {
        self.net.is_empty()
    }

    /// The underlying network.
    pub fn network(&self) -> &GammaGwr {
        &self.net
    }

    /// Node `j`'s instance label (histogram argmax).
    pub fn instance_of(&self, j: usize) -> Option<u32> {
        self.net.label(INSTANCE_LEVEL, j)
    }

    /// Node `j`'s category label (histogram argmax).
    pub fn category_of(&self, j: usize) -> Option<u32> {
        self.net.label(CATEGORY_LEVEL, j)
    }

    pub(crate) fn train_step(
        &mut self,
        x: &[f32],
        instance: Option<u32>,
        category: Option<u32>,
    ) -> StepOutcome {
        self.net
            .step(x, &[instance, category], Supervision::Unsupervised)
    }
}

/// Semantic memory G-SM: a Gamma-GWR with category histograms, growth regulated by ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SemanticMemory {
    pub(crate) net: GammaGwr,
}

impl SemanticMemory {
    /// An empty semantic memory for `dim`-dimensional inputs.
    pub fn new(params: MemoryParams, metric: Metric, dim: usize) -> Result<Self, GdmError> {
        Ok(SemanticMemory {
            net: GammaGwr::new(params, metric, dim, 1)?,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.net.len()
    }

    /// True if there is no node yet.
    pub fn is_empty(&self) -> bool {
        self.net.is_empty()
    }

    /// The underlying network.
    pub fn network(&self) -> &GammaGwr {
        &self.net
    }

    /// Node `j`'s category label (histogram argmax).
    pub fn category_of(&self, j: usize) -> Option<u32> {
        self.net.label(0, j)
    }

    pub(crate) fn train_step(&mut self, x: &[f32], category: Option<u32>) -> StepOutcome {
        self.net.step(x, &[category], Supervision::Regulated)
    }
}
