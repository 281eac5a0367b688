//! Each augmentation measurably does what it says: noise has the stated σ, voxel
//! down-sampling leaves one point per voxel, occlusion and dropout remove the stated share of
//! points, outliers add the stated count, scene augmentations move, tilt and scale the object.

use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::augment::{
    Augmentation, add_outliers, dropout, gaussian_noise, occlude, voxel_downsample,
};
use lgdm_pointcloud::dataset::{DatasetSpec, Split, standard_collections};
use lgdm_pointcloud::math::rotate_vector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn grid_cloud(n_side: usize) -> PointCloud {
    let mut points = Vec::new();
    let mut colors = Vec::new();
    for i in 0..n_side {
        for j in 0..n_side {
            points.push([
                i as f32 * 0.001 - 0.05,
                j as f32 * 0.001 - 0.05,
                0.8 + 0.0005 * (i % 7) as f32,
            ]);
            colors.push([(i % 256) as u8, (j % 256) as u8, 7]);
        }
    }
    PointCloud::new(points, Some(colors))
}

#[test]
fn gaussian_noise_has_the_stated_sigma() {
    let cloud = grid_cloud(100);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for sigma in [0.002f32, 0.004, 0.008] {
        let noisy = gaussian_noise(&cloud, sigma, &mut rng);
        assert_eq!(noisy.len(), cloud.len());
        let mut sum = 0.0f64;
        let mut sq = 0.0f64;
        for (a, b) in cloud.points.iter().zip(&noisy.points) {
            for k in 0..3 {
                let d = f64::from(b[k] - a[k]);
                sum += d;
                sq += d * d;
            }
        }
        let n = (cloud.len() * 3) as f64;
        let mean = sum / n;
        let std = (sq / n - mean * mean).sqrt();
        assert!(mean.abs() < 3e-4 * f64::from(sigma) / 0.002, "mean {mean}");
        assert!(
            (std / f64::from(sigma) - 1.0).abs() < 0.02,
            "σ {std} vs {sigma}"
        );
    }
}

#[test]
fn voxel_downsample_keeps_one_point_per_voxel() {
    let cloud = grid_cloud(100);
    for voxel in [0.005f32, 0.008, 0.012] {
        let out = voxel_downsample(&cloud, voxel);
        let key = |p: &[f32; 3]| {
            [
                (p[0] / voxel).floor() as i64,
                (p[1] / voxel).floor() as i64,
                (p[2] / voxel).floor() as i64,
            ]
        };
        let mut input_keys: Vec<_> = cloud.points.iter().map(key).collect();
        input_keys.sort();
        input_keys.dedup();
        // One output point per occupied voxel, each inside its voxel (the mean of its points).
        assert_eq!(out.len(), input_keys.len());
        let mut out_keys: Vec<_> = out.points.iter().map(key).collect();
        out_keys.sort();
        out_keys.dedup();
        assert_eq!(out_keys, input_keys);
        // Nearest-neighbour spacing is about the voxel size: no two outputs closer than ~voxel/2.
        assert!(out.len() < cloud.len());
        assert_eq!(out.colors.as_ref().unwrap().len(), out.len());
    }
}

#[test]
fn occlusion_removes_the_stated_share_from_one_side() {
    let cloud = grid_cloud(60);
    for fraction in [0.1f32, 0.3, 0.5] {
        let angle = 0.7;
        let out = occlude(&cloud, fraction, angle);
        let removed = cloud.len() - out.len();
        assert_eq!(removed, (fraction * cloud.len() as f32).round() as usize);
        // Every kept point lies on the visible side of every removed one.
        let proj = |p: &[f32; 3]| angle.cos() * p[0] / p[2] + angle.sin() * p[1] / p[2];
        let kept_max = out.points.iter().map(proj).fold(f32::MIN, f32::max);
        let removed_min = cloud
            .points
            .iter()
            .filter(|p| !out.points.contains(p))
            .map(proj)
            .fold(f32::MAX, f32::min);
        assert!(kept_max <= removed_min);
    }
}

#[test]
fn dropout_removes_the_stated_share() {
    let cloud = grid_cloud(100);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for rate in [0.2f32, 0.5, 0.8] {
        let out = dropout(&cloud, rate, &mut rng);
        let share = 1.0 - out.len() as f32 / cloud.len() as f32;
        assert!((share - rate).abs() < 0.02, "dropped {share}, rate {rate}");
        // Kept points keep their colours.
        let c = out.colors.as_ref().unwrap();
        assert_eq!(c.len(), out.len());
    }
}

#[test]
fn outliers_add_the_stated_count_inside_the_grown_box() {
    let cloud = grid_cloud(50);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let out = add_outliers(&cloud, 0.05, 0.03, &mut rng);
    assert_eq!(
        out.len() - cloud.len(),
        (0.05 * cloud.len() as f32).round() as usize
    );
    let (lo, hi) = cloud.bounds().unwrap();
    let outside = out.points[cloud.len()..]
        .iter()
        .filter(|p| (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]))
        .count();
    assert!(outside > 0, "outliers should leave the object's box");
    assert!(
        out.points[cloud.len()..]
            .iter()
            .all(|p| (0..3).all(|k| p[k] >= lo[k] - 0.03 && p[k] <= hi[k] + 0.03))
    );
}

#[test]
fn scene_augmentations_move_tilt_and_scale() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..20 {
        let p = Augmentation::Translation { max_offset_m: 0.08 }.scene_placement(&mut rng);
        let r = (p.offset_m[0].powi(2) + p.offset_m[1].powi(2)).sqrt();
        assert!(r <= 0.08 + 1e-6);
        let p = Augmentation::Scale { min: 0.8, max: 1.2 }.scene_placement(&mut rng);
        assert!((0.8..=1.2).contains(&p.scale));
        let p = Augmentation::Rotation { max_tilt_rad: 0.4 }.scene_placement(&mut rng);
        // Tilt angle from the rotation of the z axis.
        let z = rotate_vector(&p.tilt, [0.0, 0.0, 1.0]);
        let tilt = z[2].clamp(-1.0, 1.0).acos();
        assert!(tilt > 0.1 && tilt <= 0.4 + 1e-4, "tilt {tilt}");
    }
}

#[test]
fn standard_collections_are_fifteen_with_a_12_3_split() {
    let c = standard_collections();
    assert_eq!(c.len(), 15);
    assert_eq!(c.iter().filter(|c| c.split == Split::Train).count(), 12);
    let mut kinds: Vec<_> = c.iter().map(|c| c.augmentation.kind()).collect();
    kinds.sort();
    kinds.dedup();
    assert_eq!(kinds.len(), 10, "{kinds:?}");
    for c in &c {
        c.augmentation.validate().unwrap();
    }
    let paper = DatasetSpec::paper(0);
    assert_eq!(paper.views(50), 75_000);
}
