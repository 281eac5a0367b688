//! GOOD has length 3·n² (675 for n = 15), each projection block sums to 1, and the descriptor
//! does not change under rigid motion of the input or with the number of points.

use lgdm_pointcloud::good::good_descriptor;
use lgdm_pointcloud::math::{rotation_axis_angle, transform_point, translation};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Points sampled on an asymmetric "L" made of two boxes' surfaces (no symmetry plane that
/// would make the PCA axes' signs ambiguous).
fn asymmetric_shape(n: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let boxes = [
        ([0.0f32, 0.0, 0.0], [0.16f32, 0.05, 0.03]),
        ([0.0, 0.05, 0.0], [0.04, 0.09, 0.03]),
        ([0.12, -0.02, 0.03], [0.03, 0.03, 0.05]),
    ];
    let volumes: Vec<f32> = boxes.iter().map(|(_, s)| s[0] * s[1] * s[2]).collect();
    let total: f32 = volumes.iter().sum();
    (0..n)
        .map(|_| {
            let mut r = rng.random_range(0.0..total);
            let mut k = 0;
            while r > volumes[k] && k < boxes.len() - 1 {
                r -= volumes[k];
                k += 1;
            }
            let (o, s) = boxes[k];
            [
                o[0] + rng.random_range(0.0..s[0]),
                o[1] + rng.random_range(0.0..s[1]),
                o[2] + rng.random_range(0.0..s[2]),
            ]
        })
        .collect()
}

fn l1(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
}

#[test]
fn length_and_block_sums() {
    let pts = asymmetric_shape(3000, 1);
    for bins in [5usize, 10, 15] {
        let d = good_descriptor(&pts, bins).unwrap();
        assert_eq!(d.len(), 3 * bins * bins);
        for block in d.chunks(bins * bins) {
            assert!((block.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            assert!(block.iter().all(|&v| v >= 0.0));
        }
    }
    assert_eq!(good_descriptor(&pts, 15).unwrap().len(), 675);
}

#[test]
fn invariant_to_rigid_motion() {
    let pts = asymmetric_shape(5000, 2);
    let reference = good_descriptor(&pts, 15).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..10 {
        let axis = [
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ];
        let pose = translation([
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.5..2.0),
        ]) * rotation_axis_angle(axis, rng.random_range(0.0..std::f32::consts::TAU));
        let moved: Vec<[f32; 3]> = pts.iter().map(|&p| transform_point(&pose, p)).collect();
        let d = good_descriptor(&moved, 15).unwrap();
        // Identical up to points that float rounding moves across a bin edge.
        assert!(
            l1(&d, &reference) < 0.02,
            "L1 distance {}",
            l1(&d, &reference)
        );
    }
}

#[test]
fn invariant_to_point_count() {
    let dense = good_descriptor(&asymmetric_shape(40_000, 3), 15).unwrap();
    let sparse = good_descriptor(&asymmetric_shape(10_000, 4), 15).unwrap();
    let other_shape: Vec<[f32; 3]> = asymmetric_shape(10_000, 4)
        .iter()
        .map(|p| [p[0] * 0.6, p[1] * 1.5, p[2]])
        .collect();
    let other = good_descriptor(&other_shape, 15).unwrap();
    let same = l1(&dense, &sparse);
    let different = l1(&dense, &other);
    // Out of a maximum L1 distance of 6: sampling noise only, and far below a real shape change.
    assert!(same < 0.3, "same shape, 4× fewer points: L1 {same}");
    assert!(
        different > 3.0 * same,
        "different shape: L1 {different} vs {same}"
    );
}
