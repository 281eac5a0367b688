//! Success rates with their Wilson 95 % score interval — the one definition the robot's
//! results, the binary's tables and (pinned by `tests/fixtures/wilson.json`) the grasp
//! network's Python metric use.
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

/// A success rate with its Wilson 95 % interval.
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
        }
    }

    /// The rate of the items of `items` for which `success` holds.
    pub fn of<T>(items: &[T], success: impl Fn(&T) -> bool) -> Self {
        Self::new(items.iter().filter(|x| success(x)).count(), items.len())
    }

    /// `80.0 % (74.1–85.0 %, 120/150)`.
    pub fn describe(&self) -> String {
        match self.value {
            Some(v) => format!(
                "{:.1} % ({:.1}–{:.1} %, {}/{})",
                100.0 * v,
                100.0 * self.wilson_low,
                100.0 * self.wilson_high,
                self.successes,
                self.trials
            ),
            None => "– (0 trials)".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
