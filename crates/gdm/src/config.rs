//! Hyperparameters: one serde struct, [`GdmConfig`], with documented defaults, the paper's
//! presets and validation that names the bad field.
//!
//! A config file (TOML or JSON) may name a preset as its base and override any field; missing
//! fields take the preset's value (the default preset is `paper_incremental`):
//!
//! ```
//! use lgdm_gdm::{GdmConfig, Metric};
//! let text = r#"
//!     preset = "paper_batch"
//!     metric = { minkowski = { p = 3.0 } }
//!     [episodic]
//!     max_age = 50
//! "#;
//! let config: GdmConfig = toml::from_str(text).unwrap();
//! assert_eq!(config.episodic.activation_threshold, 0.7); // from paper_batch
//! assert_eq!(config.semantic.activation_threshold, 0.8); // from paper_batch
//! assert_eq!(config.episodic.max_age, 50);
//! assert_eq!(config.metric, Metric::Minkowski { p: 3.0 });
//! config.validate().unwrap();
//! ```

use serde::{Deserialize, Serialize};

use crate::error::ConfigError;
pub use crate::metric::Metric;

/// Names accepted by [`GdmConfig::preset`] (and by `preset = "…"` in a config file).
pub const PRESETS: &[&str] = &["paper_incremental", "paper_batch"];

/// Largest input dimension D a model accepts ([`Gdm::new`](crate::Gdm::new)): 2²⁰ features,
/// 4 MiB per vector. With the largest context depth a node block is then 65·2²⁰ floats.
pub const MAX_DIM: usize = 1 << 20;
/// Largest context depth K ([`MemoryParams::context_depth`]).
pub const MAX_CONTEXT_DEPTH: usize = 64;
/// Largest node cap ([`MemoryParams::max_nodes`]): 10⁷ nodes, already 81 GB of weights at
/// D = 675, K = 2.
pub const MAX_NODES: usize = 10_000_000;
/// Longest RNAT chain ([`ReplayParams::chain_length`]): K + 1 for the largest context depth.
/// One replay trains on up to nodes × chain length pseudo-samples, so a run's time grows
/// linearly with it (the NI scenario on the embedded dataset: 4.6 s at the paper's K + 1 = 3,
/// 22 s at 30, 157 s at 300; 10,000 would take over an hour). An RNAT reproduces the temporal
/// context of K + 1 consecutive samples; longer chains replay the same loops again.
pub const MAX_CHAIN_LENGTH: usize = MAX_CONTEXT_DEPTH + 1;
/// Largest replay budget ([`ReplayBudget::Learnt`]): 1000 pseudo-samples per sample learnt.
/// A budget replays every chain (as `"all"` does) once it exceeds (K+1) × nodes / samples
/// learnt, a few per sample in the paper's scenarios; a larger number is a mistake.
pub const MAX_REPLAY_BUDGET: f32 = 1000.0;
/// Most label levels of one network ([`GammaGwr::new`](crate::GammaGwr::new); the memories
/// use 1 and 2).
pub const MAX_LEVELS: usize = 64;

/// Hyperparameters of one Gamma-GWR memory (episodic or semantic).
///
/// The defaults are the episodic memory's values of the paper's incremental preset; the
/// semantic memory of [`GdmConfig::default`] differs only in its `activation_threshold` (0.7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryParams {
    /// Insertion threshold a_T on the activity a = exp(−d_b) (default: 0.5 episodic, 0.7
    /// semantic). Its useful range depends on the metric and the feature scale.
    pub activation_threshold: f32,
    /// Habituation threshold h_T: only a node fired below it may spawn a new node (default: 0.1).
    pub habituation_threshold: f32,
    /// Number K of temporal context descriptors per node (default: 2; at most
    /// [`MAX_CONTEXT_DEPTH`] = 64).
    pub context_depth: usize,
    /// Context mixing β of the global-context recursion (default: 0.4).
    pub beta: f32,
    /// Explicit context weights α_0..α_K (length K+1), used as given (default: none, meaning
    /// α_k ∝ e^{−k} normalised to sum 1; K = 2 gives 0.665, 0.245, 0.090).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alphas: Option<Vec<f32>>,
    /// Learning rate ε_b of the best-matching node (default: 0.5).
    pub epsilon_b: f32,
    /// Learning rate ε_n of the best node's neighbours (default: 0.005).
    pub epsilon_n: f32,
    /// Habituation rate τ_b of the best-matching node (default: 0.3).
    pub tau_b: f32,
    /// Habituation rate τ_n of the neighbours (default: 0.1).
    pub tau_n: f32,
    /// Habituation constant κ > 1; habituation converges to 1 − 1/κ (default: 1.05).
    pub kappa: f32,
    /// Controlled edge removal threshold N_T (default: 0.2). An edge older than `max_age` is
    /// removed only when the neighbour at its far end is poorly habituated (h > N_T); otherwise it
    /// is kept and its age reset to 0. N_T = 1 disables the control: every edge older than
    /// `max_age` is removed (plain GWR).
    pub removal_threshold: f32,
    /// Maximum edge age, in firings of the node that owns the edge (default: 100).
    pub max_age: u32,
    /// Label histogram increment δ⁺ for the sample's label (default: 1).
    pub label_increment: f32,
    /// Label histogram decrement δ⁻ for every other label, floored at 0 (default: 0.1).
    pub label_decrement: f32,
    /// Learning-rate factor ε_c applied when a regulated (semantic) memory mispredicts and does
    /// not insert (default: 0.001). Unused by the episodic memory.
    pub mod_rate: f32,
    /// Node capacity: no insertion once the memory holds this many nodes (default: none,
    /// unbounded; at least 2, at most [`MAX_NODES`] = 10⁷).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_nodes: Option<usize>,
}

impl Default for MemoryParams {
    fn default() -> Self {
        MemoryParams {
            activation_threshold: 0.5,
            habituation_threshold: 0.1,
            context_depth: 2,
            beta: 0.4,
            alphas: None,
            epsilon_b: 0.5,
            epsilon_n: 0.005,
            tau_b: 0.3,
            tau_n: 0.1,
            kappa: 1.05,
            removal_threshold: 0.2,
            max_age: 100,
            label_increment: 1.0,
            label_decrement: 0.1,
            mod_rate: 0.001,
            max_nodes: None,
        }
    }
}

impl MemoryParams {
    /// The context weights α_0..α_K in use: the explicit `alphas`, or α_k ∝ e^{−k} normalised.
    pub fn context_weights(&self) -> Vec<f32> {
        match &self.alphas {
            Some(a) => a.clone(),
            None => default_alphas(self.context_depth),
        }
    }

    /// Checks every field; `prefix` names the memory in the error (`episodic`, `semantic`).
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        let f = |name: &str| format!("{prefix}.{name}");
        let unit_open = |name: &str, v: f32| -> Result<(), ConfigError> {
            if v.is_finite() && v > 0.0 && v <= 1.0 {
                Ok(())
            } else {
                Err(ConfigError::invalid(
                    f(name),
                    format!("{v} is not in (0, 1]"),
                ))
            }
        };
        let unit_closed = |name: &str, v: f32| -> Result<(), ConfigError> {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(ConfigError::invalid(
                    f(name),
                    format!("{v} is not in [0, 1]"),
                ))
            }
        };
        unit_closed("activation_threshold", self.activation_threshold)?;
        unit_closed("habituation_threshold", self.habituation_threshold)?;
        if self.context_depth > MAX_CONTEXT_DEPTH {
            return Err(ConfigError::invalid(
                f("context_depth"),
                format!("{} is larger than {MAX_CONTEXT_DEPTH}", self.context_depth),
            ));
        }
        unit_closed("beta", self.beta)?;
        if let Some(a) = &self.alphas {
            if a.len() != self.context_depth + 1 {
                return Err(ConfigError::invalid(
                    f("alphas"),
                    format!(
                        "has {} entries, context_depth {} needs {}",
                        a.len(),
                        self.context_depth,
                        self.context_depth + 1
                    ),
                ));
            }
            if a.iter().any(|v| !v.is_finite() || *v < 0.0) {
                return Err(ConfigError::invalid(
                    f("alphas"),
                    "entries must be finite and ≥ 0",
                ));
            }
            if a[0] <= 0.0 {
                return Err(ConfigError::invalid(f("alphas"), "alphas[0] must be > 0"));
            }
        }
        unit_closed("epsilon_b", self.epsilon_b)?;
        unit_closed("epsilon_n", self.epsilon_n)?;
        unit_open("tau_b", self.tau_b)?;
        unit_open("tau_n", self.tau_n)?;
        if !(self.kappa.is_finite() && self.kappa > 1.0) {
            return Err(ConfigError::invalid(
                f("kappa"),
                format!("{} must be > 1", self.kappa),
            ));
        }
        for (name, tau) in [("tau_b", self.tau_b), ("tau_n", self.tau_n)] {
            if tau * self.kappa > 1.0 {
                return Err(ConfigError::invalid(
                    f(name),
                    format!(
                        "{tau} · kappa {} exceeds 1: habituation would leave (0, 1]",
                        self.kappa
                    ),
                ));
            }
        }
        unit_closed("removal_threshold", self.removal_threshold)?;
        if self.max_age == 0 {
            return Err(ConfigError::invalid(f("max_age"), "must be at least 1"));
        }
        if !(self.label_increment.is_finite() && self.label_increment > 0.0) {
            return Err(ConfigError::invalid(
                f("label_increment"),
                format!("{} must be > 0", self.label_increment),
            ));
        }
        if !(self.label_decrement.is_finite() && self.label_decrement >= 0.0) {
            return Err(ConfigError::invalid(
                f("label_decrement"),
                format!("{} must be ≥ 0", self.label_decrement),
            ));
        }
        unit_closed("mod_rate", self.mod_rate)?;
        if let Some(m) = self.max_nodes {
            if m < 2 {
                return Err(ConfigError::invalid(
                    f("max_nodes"),
                    format!("{m} is below the 2 initial nodes"),
                ));
            }
            if m > MAX_NODES {
                return Err(ConfigError::invalid(
                    f("max_nodes"),
                    format!("{m} is larger than {MAX_NODES} (leave it out for no cap)"),
                ));
            }
        }
        Ok(())
    }
}

/// α_k ∝ e^{−k}, k = 0..=depth, normalised to sum 1.
pub(crate) fn default_alphas(depth: usize) -> Vec<f32> {
    let raw: Vec<f64> = (0..=depth).map(|k| (-(k as f64)).exp()).collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|v| (v / sum) as f32).collect()
}

/// How many chains one replay replays (`replay.budget`).
///
/// In a config file: `budget = "all"` or `budget = 1.0` (a number of pseudo-samples per
/// sample learnt).
///
/// ```
/// use lgdm_gdm::{GdmConfig, config::ReplayBudget};
/// let c: GdmConfig = toml::from_str("[replay]\nbudget = 1.0\n").unwrap();
/// assert_eq!(c.replay.budget, ReplayBudget::Learnt(1.0));
/// let c: GdmConfig = toml::from_str("[replay]\nbudget = \"all\"\n").unwrap();
/// assert_eq!(c.replay.budget, ReplayBudget::All);
/// let c: GdmConfig = toml::from_str("[replay]\nbudget = 0\n").unwrap();
/// assert_eq!(c.validate().unwrap_err().field(), Some("replay.budget"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ReplayBudget {
    /// The paper's replay: one chain from every episodic node (about (K+1) × nodes
    /// pseudo-samples, whatever the episode learnt).
    #[default]
    All,
    /// At most this many pseudo-samples per training sample since the last replay (rounded
    /// up; the last chain is replayed whole): chains start at episodic nodes drawn without
    /// replacement with the config's seed, until the budget is spent or every node has had its
    /// chain. A pseudo-sample costs about one training sample, so 1.0 keeps a replay within
    /// about the learning time of its episode. Finite, > 0 and at most [`MAX_REPLAY_BUDGET`].
    Learnt(f32),
}

impl Serialize for ReplayBudget {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match *self {
            ReplayBudget::All => serializer.serialize_str("all"),
            ReplayBudget::Learnt(f) => serializer.serialize_f32(f),
        }
    }
}

impl<'de> Deserialize<'de> for ReplayBudget {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = ReplayBudget;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(
                    "replay.budget: \"all\" or a number of pseudo-samples per sample learnt",
                )
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ReplayBudget, E> {
                if v.eq_ignore_ascii_case("all") {
                    Ok(ReplayBudget::All)
                } else {
                    Err(E::custom(format!(
                        "replay.budget: expected \"all\" or a number of pseudo-samples per \
                         sample learnt, found \"{v}\""
                    )))
                }
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<ReplayBudget, E> {
                // Out-of-range values (even beyond f32) are kept for `validate` to name.
                Ok(ReplayBudget::Learnt(v as f32))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ReplayBudget, E> {
                Ok(ReplayBudget::Learnt(v as f32))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ReplayBudget, E> {
                Ok(ReplayBudget::Learnt(v as f32))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// Intrinsic replay settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplayParams {
    /// Length of each RNAT chain (default: none, meaning K+1 with K the episodic
    /// `context_depth`; at least 1, at most [`MAX_CHAIN_LENGTH`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chain_length: Option<usize>,
    /// Replay the chains in an order shuffled with the config's seed rather than by node id
    /// (default: true). Under a [`ReplayBudget::Learnt`] budget the chains are always drawn
    /// with the seed.
    pub shuffle: bool,
    /// How many chains one replay replays (default: `"all"`, the paper's one chain per
    /// episodic node; see [`ReplayBudget`]).
    pub budget: ReplayBudget,
}

impl Default for ReplayParams {
    fn default() -> Self {
        ReplayParams {
            chain_length: None,
            shuffle: true,
            budget: ReplayBudget::All,
        }
    }
}

/// All hyperparameters of a [`Gdm`](crate::Gdm) model.
///
/// [`GdmConfig::default`] is [`GdmConfig::paper_incremental`]. Deserialisation accepts an
/// optional `preset` key naming the base preset; fields missing from the file keep the preset's
/// values. Serialisation writes every field (and no `preset`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawConfig")]
pub struct GdmConfig {
    /// Seed of the model's random number generator (default: 0). Same seed, config and data give
    /// the same model, byte for byte.
    pub seed: u64,
    /// Distance metric of both memories (default: Manhattan, the paper's choice).
    pub metric: Metric,
    /// Episodic memory G-EM (default: a_T 0.5, the paper's incremental values).
    pub episodic: MemoryParams,
    /// Semantic memory G-SM (default: as `episodic` but a_T 0.7).
    pub semantic: MemoryParams,
    /// Intrinsic replay (default: chains of K+1 nodes, shuffled).
    pub replay: ReplayParams,
}

impl Default for GdmConfig {
    fn default() -> Self {
        GdmConfig::paper_incremental()
    }
}

impl GdmConfig {
    /// The paper's incremental-learning hyperparameters (appendix table 2): a_T EM/SM 0.5/0.7,
    /// β 0.4, ε_b 0.5, ε_n 0.005, ε_c 0.001, h_T 0.1, τ_b 0.3, τ_n 0.1, κ 1.05, N_T 0.2,
    /// δ⁺ 1, δ⁻ 0.1, K 2.
    pub fn paper_incremental() -> Self {
        let episodic = MemoryParams::default();
        let semantic = MemoryParams {
            activation_threshold: 0.7,
            ..MemoryParams::default()
        };
        GdmConfig {
            seed: 0,
            metric: Metric::Manhattan,
            episodic,
            semantic,
            replay: ReplayParams::default(),
        }
    }

    /// The paper's batch-learning hyperparameters (appendix table 1): a_T EM/SM 0.7/0.8,
    /// β 0.5, ε_b 0.3, ε_n 0.003, and otherwise as [`GdmConfig::paper_incremental`].
    pub fn paper_batch() -> Self {
        let base = MemoryParams {
            beta: 0.5,
            epsilon_b: 0.3,
            epsilon_n: 0.003,
            ..MemoryParams::default()
        };
        GdmConfig {
            episodic: MemoryParams {
                activation_threshold: 0.7,
                ..base.clone()
            },
            semantic: MemoryParams {
                activation_threshold: 0.8,
                ..base
            },
            ..GdmConfig::paper_incremental()
        }
    }

    /// Looks a preset up by name: `paper_incremental` or `paper_batch` (`-` and `_` are
    /// interchangeable, case is ignored).
    pub fn preset(name: &str) -> Result<Self, ConfigError> {
        match name.to_ascii_lowercase().replace('-', "_").as_str() {
            "paper_incremental" | "incremental" => Ok(GdmConfig::paper_incremental()),
            "paper_batch" | "batch" => Ok(GdmConfig::paper_batch()),
            _ => Err(ConfigError::UnknownPreset {
                name: name.to_string(),
                known: PRESETS.join(", "),
            }),
        }
    }

    /// Checks every field; the error names the first bad one (e.g. `episodic.beta`). Every
    /// size has a finite bound ([`MAX_CONTEXT_DEPTH`], [`MAX_NODES`], [`MAX_CHAIN_LENGTH`]), so a
    /// valid config never asks for an allocation out of proportion to the data.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.metric.validate()?;
        self.episodic.validate("episodic")?;
        self.semantic.validate("semantic")?;
        if let Some(len) = self.replay.chain_length {
            if len == 0 {
                return Err(ConfigError::invalid(
                    "replay.chain_length",
                    "must be at least 1",
                ));
            }
            if len > MAX_CHAIN_LENGTH {
                return Err(ConfigError::invalid(
                    "replay.chain_length",
                    format!(
                        "{len} is larger than {MAX_CHAIN_LENGTH} (K + 1 for the largest context \
                         depth; every replay trains on up to nodes × chain length samples)"
                    ),
                ));
            }
        }
        if let ReplayBudget::Learnt(b) = self.replay.budget
            && !(b.is_finite() && b > 0.0 && b <= MAX_REPLAY_BUDGET)
        {
            return Err(ConfigError::invalid(
                "replay.budget",
                format!(
                    "{b} must be \"all\" or a number of pseudo-samples per sample learnt, \
                     finite, > 0 and at most {MAX_REPLAY_BUDGET}"
                ),
            ));
        }
        Ok(())
    }

    /// Length of the RNAT chains in use.
    pub fn replay_chain_length(&self) -> usize {
        self.replay
            .chain_length
            .unwrap_or(self.episodic.context_depth + 1)
    }
}

/// Every field optional: what a config file may leave out.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct RawMemoryParams {
    activation_threshold: Option<f32>,
    habituation_threshold: Option<f32>,
    context_depth: Option<usize>,
    beta: Option<f32>,
    alphas: Option<Vec<f32>>,
    epsilon_b: Option<f32>,
    epsilon_n: Option<f32>,
    tau_b: Option<f32>,
    tau_n: Option<f32>,
    kappa: Option<f32>,
    removal_threshold: Option<f32>,
    max_age: Option<u32>,
    label_increment: Option<f32>,
    label_decrement: Option<f32>,
    mod_rate: Option<f32>,
    max_nodes: Option<usize>,
}

impl RawMemoryParams {
    fn apply(self, mut p: MemoryParams) -> MemoryParams {
        macro_rules! set {
            ($($f:ident),*) => { $( if let Some(v) = self.$f { p.$f = v; } )* };
        }
        set!(
            activation_threshold,
            habituation_threshold,
            context_depth,
            beta,
            epsilon_b,
            epsilon_n,
            tau_b,
            tau_n,
            kappa,
            removal_threshold,
            max_age,
            label_increment,
            label_decrement,
            mod_rate
        );
        if self.alphas.is_some() {
            p.alphas = self.alphas;
        }
        if self.max_nodes.is_some() {
            p.max_nodes = self.max_nodes;
        }
        p
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct RawConfig {
    preset: Option<String>,
    seed: Option<u64>,
    metric: Option<Metric>,
    episodic: RawMemoryParams,
    semantic: RawMemoryParams,
    replay: Option<ReplayParams>,
}

impl TryFrom<RawConfig> for GdmConfig {
    type Error = ConfigError;

    fn try_from(raw: RawConfig) -> Result<Self, Self::Error> {
        let base = match &raw.preset {
            Some(name) => GdmConfig::preset(name)?,
            None => GdmConfig::default(),
        };
        Ok(GdmConfig {
            seed: raw.seed.unwrap_or(base.seed),
            metric: raw.metric.unwrap_or(base.metric),
            episodic: raw.episodic.apply(base.episodic),
            semantic: raw.semantic.apply(base.semantic),
            replay: raw.replay.unwrap_or(base.replay),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_hold_the_paper_values() {
        let b = GdmConfig::paper_batch();
        assert_eq!(b.episodic.activation_threshold, 0.7);
        assert_eq!(b.semantic.activation_threshold, 0.8);
        assert_eq!(
            (b.episodic.beta, b.episodic.epsilon_b, b.episodic.epsilon_n),
            (0.5, 0.3, 0.003)
        );
        let i = GdmConfig::paper_incremental();
        assert_eq!(i.episodic.activation_threshold, 0.5);
        assert_eq!(i.semantic.activation_threshold, 0.7);
        assert_eq!(
            (i.semantic.beta, i.semantic.epsilon_b, i.semantic.epsilon_n),
            (0.4, 0.5, 0.005)
        );
        for c in [&b, &i] {
            for m in [&c.episodic, &c.semantic] {
                assert_eq!(m.mod_rate, 0.001);
                assert_eq!(m.habituation_threshold, 0.1);
                assert_eq!((m.tau_b, m.tau_n, m.kappa), (0.3, 0.1, 1.05));
                assert_eq!(m.removal_threshold, 0.2);
                assert_eq!((m.label_increment, m.label_decrement), (1.0, 0.1));
                assert_eq!(m.context_depth, 2);
            }
            c.validate().unwrap();
        }
        assert_eq!(GdmConfig::preset("paper-batch").unwrap(), b);
        assert_eq!(GdmConfig::preset("paper_incremental").unwrap(), i);
        assert!(matches!(
            GdmConfig::preset("nope"),
            Err(ConfigError::UnknownPreset { .. })
        ));
    }

    #[test]
    fn default_alphas_match_design() {
        let a = default_alphas(2);
        assert!((a[0] - 0.665).abs() < 1e-3, "{a:?}");
        assert!((a[1] - 0.245).abs() < 1e-3, "{a:?}");
        assert!((a[2] - 0.090).abs() < 1e-3, "{a:?}");
        assert_eq!(default_alphas(0), vec![1.0]);
    }

    #[test]
    fn validation_names_the_field() {
        let mut c = GdmConfig::default();
        c.episodic.activation_threshold = 1.5;
        assert_eq!(
            c.validate().unwrap_err().field(),
            Some("episodic.activation_threshold")
        );
        let mut c = GdmConfig::default();
        c.semantic.kappa = 0.9;
        assert_eq!(c.validate().unwrap_err().field(), Some("semantic.kappa"));
        let mut c = GdmConfig::default();
        c.episodic.alphas = Some(vec![1.0]);
        assert_eq!(c.validate().unwrap_err().field(), Some("episodic.alphas"));
        let c = GdmConfig {
            metric: Metric::Minkowski { p: 0.5 },
            ..GdmConfig::default()
        };
        assert_eq!(c.validate().unwrap_err().field(), Some("metric.p"));
        let mut c = GdmConfig::default();
        c.semantic.tau_b = 0.99;
        assert_eq!(c.validate().unwrap_err().field(), Some("semantic.tau_b"));
        let mut c = GdmConfig::default();
        c.episodic.beta = f32::NAN;
        assert_eq!(c.validate().unwrap_err().field(), Some("episodic.beta"));
    }

    #[test]
    fn sizes_have_finite_bounds_naming_the_field() {
        let check = |edit: &dyn Fn(&mut GdmConfig), field: &str| {
            let mut c = GdmConfig::default();
            edit(&mut c);
            let e = c.validate().unwrap_err();
            assert_eq!(e.field(), Some(field), "{e}");
        };
        check(
            &|c| c.replay.chain_length = Some(MAX_CHAIN_LENGTH + 1),
            "replay.chain_length",
        );
        check(
            &|c| c.replay.chain_length = Some(1_000_000_000),
            "replay.chain_length",
        );
        check(&|c| c.replay.chain_length = Some(0), "replay.chain_length");
        // Reported: 10,000 was accepted and turned a 1.5 s run into more than 300 s.
        check(
            &|c| c.replay.chain_length = Some(10_000),
            "replay.chain_length",
        );
        check(
            &|c| c.episodic.max_nodes = Some(MAX_NODES + 1),
            "episodic.max_nodes",
        );
        check(
            &|c| c.semantic.max_nodes = Some(usize::MAX),
            "semantic.max_nodes",
        );
        check(
            &|c| c.semantic.context_depth = MAX_CONTEXT_DEPTH + 1,
            "semantic.context_depth",
        );
        // The bounds themselves are allowed.
        let mut c = GdmConfig::default();
        c.replay.chain_length = Some(MAX_CHAIN_LENGTH);
        c.episodic.max_nodes = Some(MAX_NODES);
        c.semantic.context_depth = MAX_CONTEXT_DEPTH;
        c.validate().unwrap();
        // The reported case: a TOML file with a huge chain length.
        let c: GdmConfig = toml::from_str("[replay]\nchain_length = 1000000000\n").unwrap();
        assert_eq!(
            c.validate().unwrap_err().field(),
            Some("replay.chain_length")
        );
    }

    #[test]
    fn replay_budget_is_all_or_a_bounded_positive_number() {
        let parse = |text: &str| toml::from_str::<GdmConfig>(text);
        assert_eq!(GdmConfig::default().replay.budget, ReplayBudget::All);
        for (text, want) in [
            ("budget = \"all\"", ReplayBudget::All),
            ("budget = \"ALL\"", ReplayBudget::All),
            ("budget = 1.0", ReplayBudget::Learnt(1.0)),
            ("budget = 2", ReplayBudget::Learnt(2.0)),
            ("budget = 0.25", ReplayBudget::Learnt(0.25)),
        ] {
            let c = parse(&format!("[replay]\n{text}\n")).unwrap();
            assert_eq!(c.replay.budget, want, "{text}");
            c.validate().unwrap();
        }
        for text in [
            "budget = 0",
            "budget = -1.0",
            "budget = nan",
            "budget = inf",
            "budget = 1e9",
            "budget = 1e300",
        ] {
            let c = parse(&format!("[replay]\n{text}\n")).unwrap();
            let e = c.validate().unwrap_err();
            assert_eq!(e.field(), Some("replay.budget"), "{text}: {e}");
        }
        for text in ["budget = \"some\"", "budget = true", "budget = [1]"] {
            let e = parse(&format!("[replay]\n{text}\n")).unwrap_err();
            assert!(e.to_string().contains("replay.budget"), "{text}: {e}");
        }
        let mut c = GdmConfig::default();
        c.replay.budget = ReplayBudget::Learnt(MAX_REPLAY_BUDGET);
        c.validate().unwrap();
        // Both forms survive TOML and JSON.
        for budget in [ReplayBudget::All, ReplayBudget::Learnt(0.5)] {
            c.replay.budget = budget;
            let back: GdmConfig = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
            assert_eq!(back, c);
            let back: GdmConfig =
                serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
            assert_eq!(back, c);
        }
    }

    #[test]
    fn toml_and_json_round_trip() {
        let mut c = GdmConfig::paper_batch();
        c.metric = Metric::Minkowski { p: 3.0 };
        c.episodic.max_nodes = Some(500);
        c.semantic.alphas = Some(vec![0.5, 0.3, 0.2]);
        let text = toml::to_string(&c).unwrap();
        let back: GdmConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, c);
        let json = serde_json::to_string(&c).unwrap();
        let back: GdmConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back, c);
        let empty: GdmConfig = toml::from_str("").unwrap();
        assert_eq!(empty, GdmConfig::default());
        let partial: GdmConfig = toml::from_str("[semantic]\nbeta = 0.9\n").unwrap();
        assert_eq!(partial.semantic.beta, 0.9);
        assert_eq!(partial.semantic.activation_threshold, 0.7);
        assert!(toml::from_str::<GdmConfig>("[episodic]\nbogus = 1\n").is_err());
        assert!(toml::from_str::<GdmConfig>("preset = \"nope\"\n").is_err());
        let metric: GdmConfig = toml::from_str("metric = \"mahalanobis\"\n").unwrap();
        assert_eq!(metric.metric, Metric::Mahalanobis);
    }
}
