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
}
