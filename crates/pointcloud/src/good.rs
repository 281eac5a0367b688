//! The GOOD shape descriptor (Global Orthographic Object Descriptor, Kasaei et al. 2016), the
//! embedded default feature of a view.
//!
//! 1. Local reference frame by PCA of the points: X = largest variance, Z = smallest, each
//!    sign-disambiguated by point counts (the axis points to the side holding more points;
//!    ties broken by the third moment, then +), Y = Z × X (right-handed).
//! 2. Three orthographic projections of the points in that frame (onto the XoZ, YoZ and XoY
//!    planes), each onto a square of side (largest extent + 2 cm) centred on the points'
//!    bounding box, split into `bins × bins` cells and normalised to sum 1.
//! 3. Concatenated with the highest-entropy projection first, the other two by increasing
//!    variance of the flattened bin index. Length `3 × bins²` (675 for 15 bins).
//!
//! The result does not depend on the pose of the input (rigid motions) and, up to sampling
//! noise, not on the number of points.
//!
//! `bins` must lie in `1..=`[`MAX_BINS`] (256: 196,608 values, far finer than any point cloud
//! fills); [`check_bins`] is the one check, used by every entry point (the cli's `--bins`,
//! Python's `good_descriptor` / `good_features`) before anything is allocated.
//!
//! ```
//! use lgdm_pointcloud::good::good_descriptor;
//! let points: Vec<[f32; 3]> = (0..500)
//!     .map(|i| { let t = i as f32 * 0.01; [t.cos() * 0.05, t.sin() * 0.03, t * 0.002] })
//!     .collect();
//! let d = good_descriptor(&points, 15).unwrap();
//! assert_eq!(d.len(), 675);
//! assert!((d[..225].iter().sum::<f32>() - 1.0).abs() < 1e-4);
//! ```

use nalgebra::{Matrix3, Vector3};

/// Margin added to the largest extent for the projection square, metres.
pub const GOOD_MARGIN_M: f64 = 0.02;

/// The largest number of bins per projection side: 256 (3 × 256² = 196,608 values, 768 KiB per
/// descriptor). A view of a few thousand points leaves almost every cell of a finer grid empty.
pub const MAX_BINS: usize = 256;

/// Checks a bin count against `1..=`[`MAX_BINS`].
pub fn check_bins(bins: usize) -> Result<(), GoodError> {
    if (1..=MAX_BINS).contains(&bins) {
        Ok(())
    } else {
        Err(GoodError::InvalidBins(bins))
    }
}

/// Errors of [`good_descriptor`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GoodError {
    /// The cloud has no points.
    #[error("GOOD descriptor of an empty point cloud")]
    Empty,
    /// `bins` is outside `1..=`[`MAX_BINS`].
    #[error("GOOD parameter `bins` must be in 1..={MAX_BINS} (got {0})")]
    InvalidBins(usize),
    /// The output buffer of [`good_descriptor_into`] does not hold `3 × bins²` values.
    #[error("GOOD output buffer holds {got} values, `bins` = {bins} needs {expected}")]
    OutputLength {
        /// The bins per side.
        bins: usize,
        /// `3 × bins²`.
        expected: usize,
        /// The buffer's length.
        got: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the first bad point.
        index: usize,
    },
}

/// The GOOD descriptor of `points` (metres, any frame) with `bins × bins` cells per projection.
pub fn good_descriptor(points: &[[f32; 3]], bins: usize) -> Result<Vec<f32>, GoodError> {
    check_bins(bins)?;
    let mut out = vec![0.0f32; 3 * bins * bins];
    good_descriptor_into(points, bins, &mut out)?;
    Ok(out)
}

/// [`good_descriptor`] writing into `out` (length `3 × bins²`, else
/// [`GoodError::OutputLength`]), to reuse buffers.
pub fn good_descriptor_into(
    points: &[[f32; 3]],
    bins: usize,
    out: &mut [f32],
) -> Result<(), GoodError> {
    check_bins(bins)?;
    if points.is_empty() {
        return Err(GoodError::Empty);
    }
    if out.len() != 3 * bins * bins {
        return Err(GoodError::OutputLength {
            bins,
            expected: 3 * bins * bins,
            got: out.len(),
        });
    }
    if let Some(index) = points.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(GoodError::NonFinite { index });
    }
    let n = points.len() as f64;
    let mut c = Vector3::<f64>::zeros();
    for p in points {
        c += Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
    }
    c /= n;
    let mut cov = Matrix3::<f64>::zeros();
    for p in points {
        let d = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) - c;
        cov += d * d.transpose();
    }
    cov /= n;
    let eig = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| {
        eig.eigenvalues[b]
            .total_cmp(&eig.eigenvalues[a])
            .then(a.cmp(&b))
    });
    let mut x_axis: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
    let mut z_axis: Vector3<f64> = eig.eigenvectors.column(order[2]).into();
    let sign_of = |axis: &Vector3<f64>| -> f64 {
        let (mut pos, mut neg, mut m3) = (0i64, 0i64, 0.0f64);
        for p in points {
            let d = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) - c;
            let s = d.dot(axis);
            if s >= 0.0 {
                pos += 1;
            } else {
                neg += 1;
            }
            m3 += s * s * s;
        }
        if pos != neg {
            if pos > neg { 1.0 } else { -1.0 }
        } else if m3 < 0.0 {
            -1.0
        } else {
            1.0
        }
    };
    x_axis *= sign_of(&x_axis);
    z_axis *= sign_of(&z_axis);
    let y_axis = z_axis.cross(&x_axis);
    // Points in the local frame.
    let local: Vec<[f64; 3]> = points
        .iter()
        .map(|p| {
            let d = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) - c;
            [d.dot(&x_axis), d.dot(&y_axis), d.dot(&z_axis)]
        })
        .collect();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in &local {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let side = extent + GOOD_MARGIN_M;
    let mid = [
        (lo[0] + hi[0]) / 2.0,
        (lo[1] + hi[1]) / 2.0,
        (lo[2] + hi[2]) / 2.0,
    ];
    let bin = |v: f64, k: usize| -> usize {
        let t = (v - (mid[k] - side / 2.0)) / side * bins as f64;
        (t.floor().max(0.0) as usize).min(bins - 1)
    };
    // Projections: (column axis, row axis) = XoZ, YoZ, XoY.
    const PLANES: [(usize, usize); 3] = [(0, 2), (1, 2), (0, 1)];
    let cells = bins * bins;
    let mut hist = vec![0u32; 3 * cells];
    for q in &local {
        for (p, &(a, b)) in PLANES.iter().enumerate() {
            hist[p * cells + bin(q[b], b) * bins + bin(q[a], a)] += 1;
        }
    }
    let mut stats = [(0.0f64, 0.0f64); 3]; // (entropy, variance of the flattened index)
    for (p, s) in stats.iter_mut().enumerate() {
        let h = &hist[p * cells..(p + 1) * cells];
        let (mut entropy, mut mean) = (0.0, 0.0);
        for (k, &count) in h.iter().enumerate() {
            if count > 0 {
                let prob = f64::from(count) / n;
                entropy -= prob * prob.ln();
                mean += k as f64 * prob;
            }
        }
        let var: f64 = h
            .iter()
            .enumerate()
            .map(|(k, &count)| f64::from(count) / n * (k as f64 - mean).powi(2))
            .sum();
        *s = (entropy, var);
    }
    // Highest entropy first (ties: lower plane index), then the others by increasing variance.
    let first = (0..3)
        .max_by(|&a, &b| stats[a].0.total_cmp(&stats[b].0).then(b.cmp(&a)))
        .unwrap_or(0);
    let mut rest: Vec<usize> = (0..3).filter(|&p| p != first).collect();
    rest.sort_by(|&a, &b| stats[a].1.total_cmp(&stats[b].1).then(a.cmp(&b)));
    for (slot, &p) in std::iter::once(&first).chain(rest.iter()).enumerate() {
        let h = &hist[p * cells..(p + 1) * cells];
        for (o, &count) in out[slot * cells..(slot + 1) * cells].iter_mut().zip(h) {
            *o = (f64::from(count) / n) as f32;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_instead_of_panics() {
        assert_eq!(good_descriptor(&[], 15), Err(GoodError::Empty));
        assert_eq!(
            good_descriptor(&[[0.0; 3]], 0),
            Err(GoodError::InvalidBins(0))
        );
        assert_eq!(
            good_descriptor_into(&[[0.0; 3]], 2, &mut [0.0; 11]),
            Err(GoodError::OutputLength {
                bins: 2,
                expected: 12,
                got: 11
            })
        );
        assert_eq!(
            good_descriptor(&[[0.0; 3], [f32::NAN, 0.0, 0.0]], 15),
            Err(GoodError::NonFinite { index: 1 })
        );
        // A single point is degenerate but defined.
        let d = good_descriptor(&[[0.1, 0.2, 0.3]], 5).unwrap();
        assert_eq!(d.len(), 75);
        assert!((d.iter().sum::<f32>() - 3.0).abs() < 1e-6);
    }

    #[test]
    fn bins_are_bounded_before_anything_is_allocated() {
        // 100,000 bins would ask for 3 × 10¹⁰ floats (120 GB).
        for bins in [MAX_BINS + 1, 100_000, usize::MAX] {
            assert_eq!(
                good_descriptor(&[[0.0; 3]], bins),
                Err(GoodError::InvalidBins(bins))
            );
        }
        let msg = GoodError::InvalidBins(100_000).to_string();
        assert!(msg.contains("`bins`") && msg.contains("256"), "{msg}");
        assert_eq!(
            good_descriptor(&[[0.0; 3]], MAX_BINS).unwrap().len(),
            196_608
        );
    }
}
