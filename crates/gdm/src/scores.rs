//! Evaluation metrics: accuracy helpers, quantization error and node counts.
//!
//! ```
//! use lgdm_gdm::scores::accuracy;
//! // (predicted, truth); pairs without a truth are skipped.
//! let acc = accuracy([(Some(1), Some(1)), (Some(2), Some(1)), (None, None)]);
//! assert_eq!(acc, 0.5);
//! assert!(accuracy(std::iter::empty()).is_nan());
//! ```

/// Scores of [`Gdm::evaluate`](crate::Gdm::evaluate). Accuracies are in [0, 1] (NaN when no
/// sample carries that label); quantization errors are mean best-node distances d_b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// Samples evaluated.
    pub n: usize,
    /// Episodic instance accuracy over samples with an instance label.
    pub instance_accuracy: f64,
    /// Episodic category accuracy over samples with a category label.
    pub category_accuracy_em: f64,
    /// Semantic category accuracy over samples with a category label.
    pub category_accuracy_sm: f64,
    /// Mean episodic best-node distance.
    pub quantization_error_em: f64,
    /// Mean semantic best-node distance.
    pub quantization_error_sm: f64,
}

/// Fraction of `(predicted, truth)` pairs with `predicted == truth`, over pairs whose truth is
/// known (a missing prediction counts as wrong). NaN if no pair has a truth.
pub fn accuracy(pairs: impl IntoIterator<Item = (Option<u32>, Option<u32>)>) -> f64 {
    let (mut right, mut total) = (0usize, 0usize);
    for (p, t) in pairs {
        if let Some(t) = t {
            total += 1;
            right += usize::from(p == Some(t));
        }
    }
    if total == 0 {
        f64::NAN
    } else {
        right as f64 / total as f64
    }
}

/// Mean of the values (NaN for none).
pub fn mean(values: impl IntoIterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for v in values {
        sum += v;
        n += 1;
    }
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// Mean and sample standard deviation (0 for a single value; NaN for none), for averages over
/// trials.
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let m = mean(values.iter().copied());
    let sd = if values.len() < 2 {
        if values.is_empty() { f64::NAN } else { 0.0 }
    } else {
        (values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (values.len() - 1) as f64).sqrt()
    };
    (m, sd)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accuracy_skips_unlabelled_and_counts_missing_predictions_wrong() {
        let acc = accuracy([
            (Some(3), Some(3)),
            (None, Some(3)),
            (Some(1), None),
            (Some(2), Some(2)),
        ]);
        assert!((acc - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn mean_std_by_hand() {
        let (m, sd) = mean_std(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        assert!((sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_std(&[7.0]), (7.0, 0.0));
    }
}
