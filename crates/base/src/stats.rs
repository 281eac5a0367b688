//! Success rates with their Wilson 95 % score interval — the one definition the robot's
//! results, the binary's tables and (pinned by `tests/fixtures/wilson.json`) the grasp
//! network's Python metric use — and, where trials come in clusters that share a cause (the
//! attempts of one round share a table; retries share an object), a seeded cluster-bootstrap
//! interval next to it ([`cluster_bootstrap`], [`Rate::with_clusters`]).
//!
//! ```
//! use lgdm_base::stats::{Rate, wilson_interval};
//! let (lo, hi) = wilson_interval(8, 10);
//! assert!((lo - 0.4902).abs() < 1e-4 && (hi - 0.9433).abs() < 1e-4);
//! assert_eq!(wilson_interval(0, 6).0, 0.0);
//! assert_eq!(wilson_interval(10, 10).1, 1.0);
//! assert_eq!(Rate::new(0, 0).value, None);
//! ```

use serde::{Deserialize, Serialize};

/// z of the two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// The Wilson score interval of a binomial proportion at 95 %; (0, 1) for no trials. Exact at
/// the ends: no successes give a low end of 0, no failures a high end of 1 (the formula's
/// rounding would miss them).
pub fn wilson_interval(successes: usize, trials: usize) -> (f64, f64) {
    if trials == 0 {
        return (0.0, 1.0);
    }
    let z = Z95;
    let n = trials as f64;
    let p = successes.min(trials) as f64 / n;
    let z2 = z * z;
    let denom = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / denom;
    let half = z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / denom;
    let low = if successes == 0 {
        0.0
    } else {
        (centre - half).max(0.0)
    };
    let high = if successes >= trials {
        1.0
    } else {
        (centre + half).min(1.0)
    };
    (low, high)
}

/// Resamples of [`cluster_bootstrap`].
pub const BOOTSTRAP_RESAMPLES: usize = 2000;

/// A 95 % percentile interval of a rate from a bootstrap over clusters of trials.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ClusterInterval {
    /// Lower end (the 2.5 % quantile of the resampled rates).
    pub low: f64,
    /// Upper end (the 97.5 % quantile).
    pub high: f64,
    /// Clusters that held at least one trial (those resampled).
    pub clusters: usize,
    /// Resamples drawn ([`BOOTSTRAP_RESAMPLES`]).
    pub resamples: usize,
}

/// The 95 % percentile-bootstrap interval of the pooled rate Σ successes / Σ trials when the
/// trials come in `clusters` of (successes, trials): the clusters (not the trials) are drawn
/// with replacement, so trials that fail or succeed together widen it as they should. Seeded:
/// the same clusters and `seed` give the same interval. `None` without trials; a single cluster
/// gives its rate at both ends (one cluster says nothing about the spread between clusters).
///
/// ```
/// use lgdm_base::stats::cluster_bootstrap;
/// // 10 rounds of 5 attempts, 40 successes: spread evenly, then all failures in two rounds.
/// let even = cluster_bootstrap(&[(4, 5); 10], 0).unwrap();
/// let lumped: Vec<(usize, usize)> = (0..10).map(|i| (if i < 8 { 5 } else { 0 }, 5)).collect();
/// let lumped = cluster_bootstrap(&lumped, 0).unwrap();
/// assert!(even.low <= 0.8 && 0.8 <= even.high);
/// assert!(lumped.high - lumped.low > even.high - even.low);
/// assert_eq!(cluster_bootstrap(&[(0, 0)], 0), None);
/// ```
pub fn cluster_bootstrap(clusters: &[(usize, usize)], seed: u64) -> Option<ClusterInterval> {
    let held: Vec<(usize, usize)> = clusters
        .iter()
        .map(|&(s, n)| (s.min(n), n))
        .filter(|&(_, n)| n > 0)
        .collect();
    let k = held.len();
    if k == 0 {
        return None;
    }
    let mut state = crate::seed::derive_seed(seed, TAG_BOOTSTRAP, k as u64, 0);
    let mut draw = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let x = crate::seed::splitmix64(state);
        // Lemire's multiply-shift: an index in 0..k.
        ((u128::from(x) * k as u128) >> 64) as usize
    };
    let mut rates: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| {
            let (mut s, mut n) = (0usize, 0usize);
            for _ in 0..k {
                let (cs, cn) = held[draw()];
                s += cs;
                n += cn;
            }
            s as f64 / n as f64
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    Some(ClusterInterval {
        low: quantile(&rates, 0.025),
        high: quantile(&rates, 0.975),
        clusters: k,
        resamples: BOOTSTRAP_RESAMPLES,
    })
}

/// The stream tag of [`cluster_bootstrap`]'s draws ([`crate::seed::derive_seed`]).
const TAG_BOOTSTRAP: u64 = 0x5133_0040;

/// The `q` quantile of sorted `values`, interpolated linearly between order statistics.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let at = q * (sorted.len() - 1) as f64;
    let (i, f) = (at.floor() as usize, at.fract());
    match sorted.get(i + 1) {
        Some(next) => sorted[i] + f * (next - sorted[i]),
        None => sorted[i],
    }
}

/// A success rate with its Wilson 95 % interval (and, where its trials come in clusters, the
/// cluster-bootstrap interval: [`Rate::with_clusters`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rate {
    /// Successes.
    pub successes: usize,
    /// Trials.
    pub trials: usize,
    /// successes / trials (`null` when there were no trials).
    pub value: Option<f64>,
    /// Lower end of the Wilson 95 % interval.
    pub wilson_low: f64,
    /// Upper end.
    pub wilson_high: f64,
    /// The 95 % interval of a bootstrap over the clusters the trials came in (the robot's:
    /// rounds); absent where the trials were not grouped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster_bootstrap: Option<ClusterInterval>,
}

impl Rate {
    /// The rate of `successes` in `trials`.
    pub fn new(successes: usize, trials: usize) -> Self {
        let (wilson_low, wilson_high) = wilson_interval(successes, trials);
        Self {
            successes,
            trials,
            value: (trials > 0).then(|| successes as f64 / trials as f64),
            wilson_low,
            wilson_high,
            cluster_bootstrap: None,
        }
    }

    /// The rate with its [`cluster_bootstrap`] interval: `clusters` hold (successes, trials)
    /// per cluster and must add up to the rate's own counts (else the rate is returned as it
    /// was: an interval of other counts would mislead).
    pub fn with_clusters(self, clusters: &[(usize, usize)], seed: u64) -> Self {
        let s: usize = clusters.iter().map(|c| c.0).sum();
        let n: usize = clusters.iter().map(|c| c.1).sum();
        if (s, n) != (self.successes, self.trials) {
            return self;
        }
        Self {
            cluster_bootstrap: cluster_bootstrap(clusters, seed),
            ..self
        }
    }

    /// The rate of the items of `items` for which `success` holds.
    pub fn of<T>(items: &[T], success: impl Fn(&T) -> bool) -> Self {
        Self::new(items.iter().filter(|x| success(x)).count(), items.len())
    }

    /// `80.0 % (74.1–85.0 %, 120/150)`; with a cluster-bootstrap interval
    /// `80.0 % (74.1–85.0 %, 120/150; clustered 71.3–87.0 %)`.
    pub fn describe(&self) -> String {
        let Some(v) = self.value else {
            return "– (0 trials)".into();
        };
        let clustered = match self.cluster_bootstrap {
            Some(c) => format!("; clustered {:.1}–{:.1} %", 100.0 * c.low, 100.0 * c.high),
            None => String::new(),
        };
        format!(
            "{:.1} % ({:.1}–{:.1} %, {}/{}{clustered})",
            100.0 * v,
            100.0 * self.wilson_low,
            100.0 * self.wilson_high,
            self.successes,
            self.trials
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cluster_bootstrap_is_seeded_and_brackets_the_rate() {
        let clusters: Vec<(usize, usize)> = (0..40).map(|i| (3 + i % 3, 5)).collect();
        let a = cluster_bootstrap(&clusters, 7).unwrap();
        assert_eq!(Some(a), cluster_bootstrap(&clusters, 7));
        // The seed moves the draws (the ends are multiples of 1/200 here, so some seeds agree).
        let ends: std::collections::BTreeSet<(u64, u64)> = (0..10)
            .map(|seed| cluster_bootstrap(&clusters, seed).unwrap())
            .map(|c| (c.low.to_bits(), c.high.to_bits()))
            .collect();
        assert!(ends.len() > 1);
        let (s, n) = clusters.iter().fold((0, 0), |(s, n), c| (s + c.0, n + c.1));
        let rate = s as f64 / n as f64;
        assert!(a.low < rate && rate < a.high, "{a:?} vs {rate}");
        assert_eq!((a.clusters, a.resamples), (40, BOOTSTRAP_RESAMPLES));
        // Clusters without trials are not drawn.
        let mut with_empty = clusters.clone();
        with_empty.push((0, 0));
        assert_eq!(cluster_bootstrap(&with_empty, 7).unwrap().clusters, 40);
    }

    #[test]
    fn clusters_that_fail_together_widen_the_interval_beyond_wilson() {
        // 30 rounds of 10 attempts, 240 successes: all-or-nothing rounds against even ones.
        let lumped: Vec<(usize, usize)> =
            (0..30).map(|i| (if i < 24 { 10 } else { 0 }, 10)).collect();
        let even = vec![(8, 10); 30];
        let r = Rate::new(240, 300);
        let lumped = r.with_clusters(&lumped, 0).cluster_bootstrap.unwrap();
        let even = r.with_clusters(&even, 0).cluster_bootstrap.unwrap();
        assert!(
            lumped.high - lumped.low > 1.5 * (r.wilson_high - r.wilson_low),
            "{lumped:?}"
        );
        assert!(
            even.high - even.low < r.wilson_high - r.wilson_low,
            "{even:?}"
        );
    }

    #[test]
    fn all_successes_and_mismatched_clusters() {
        let all = cluster_bootstrap(&[(5, 5), (3, 3)], 0).unwrap();
        assert_eq!((all.low, all.high), (1.0, 1.0));
        // Clusters of other counts than the rate's: no interval.
        assert_eq!(
            Rate::new(4, 6)
                .with_clusters(&[(1, 3)], 0)
                .cluster_bootstrap,
            None
        );
        let r = Rate::new(4, 6).with_clusters(&[(1, 3), (3, 3)], 0);
        assert!(r.describe().contains("; clustered "), "{}", r.describe());
        assert!(!Rate::new(4, 6).describe().contains("clustered"));
    }

    /// The values both languages are pinned to (`python/train_ae/tests` reads the same file).
    #[test]
    fn matches_the_shared_fixture() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../tests/fixtures/wilson.json"
        );
        let text = std::fs::read_to_string(path).expect("tests/fixtures/wilson.json");
        let rows: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
        assert!(rows.len() >= 8, "{} rows", rows.len());
        for row in rows {
            let k = row["successes"].as_u64().unwrap() as usize;
            let n = row["trials"].as_u64().unwrap() as usize;
            let (lo, hi) = wilson_interval(k, n);
            let want = (row["low"].as_f64().unwrap(), row["high"].as_f64().unwrap());
            assert!(
                (lo - want.0).abs() < 1e-12 && (hi - want.1).abs() < 1e-12,
                "{k}/{n}: ({lo}, {hi}) against {want:?}"
            );
        }
    }

    #[test]
    fn the_interval_holds_the_rate_and_narrows_with_trials() {
        for n in [1usize, 3, 10, 100, 1000] {
            for k in 0..=n.min(12) {
                let r = Rate::new(k, n);
                let v = r.value.unwrap();
                assert!(r.wilson_low <= v && v <= r.wilson_high, "{k}/{n}");
            }
        }
        let w = |n| {
            let (lo, hi) = wilson_interval(n / 2, n);
            hi - lo
        };
        assert!(w(10) > w(100) && w(100) > w(1000));
    }
}
