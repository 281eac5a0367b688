//! Grasp decoding (the golden fixture of `grasp_convention.rs` pins it to train_ae): rectangles → label maps → decoding gives the rectangles
//! back (through the ±90° wrap too), peaks within the minimum distance of a better one or below
//! the threshold are dropped, the order is deterministic, pixel → camera follows the pinhole
//! model, and bad input is a typed error, never a panic.

use lgdm_pointcloud::grasp::GraspRectangle;
use lgdm_pointcloud::grasp::decode::{
    DecodedGrasp, GraspDecodeError, GraspDecodeParams, GraspMaps, InputCrop, WIDTH_SCALE_PX,
    angle_difference, decode_grasps, grasp_angle, grasp_maps, grasp_pose, wrap_angle,
};
use lgdm_pointcloud::math::{rotate_vector, transform_point};
use lgdm_pointcloud::render::Intrinsics;

/// A rectangle in train_ae's parametrisation: θ in degrees counter-clockwise on screen.
fn rect(cx: f32, cy: f32, theta_deg: f32, width_px: f32, jaw_px: f32) -> GraspRectangle {
    GraspRectangle::from_center([cx, cy], -theta_deg.to_radians(), width_px, jaw_px)
}

fn at(maps: &GraspMaps, row: usize, col: usize) -> usize {
    row * maps.cols + col
}

/// No smoothing, many grasps: peaks are exactly the values put in.
fn raw_params() -> GraspDecodeParams {
    GraspDecodeParams {
        num_grasps: 20,
        quality_sigma_px: 0.0,
        width_sigma_px: 0.0,
        ..GraspDecodeParams::default()
    }
}

fn with_spikes(rows: usize, cols: usize, spikes: &[(usize, usize, f32)]) -> GraspMaps {
    let mut maps = GraspMaps::zeros(rows, cols);
    for &(r, c, q) in spikes {
        let i = at(&maps, r, c);
        maps.quality[i] = q;
        maps.cos2t[i] = 1.0;
        maps.width[i] = 0.2;
    }
    maps
}

fn centers(grasps: &[DecodedGrasp]) -> Vec<[f32; 2]> {
    grasps.iter().map(|g| g.center_px).collect()
}

#[test]
fn label_maps_mark_the_centre_third_as_train_ae() {
    // train_ae tests/test_grasp.py::test_label_maps_mark_the_centre_third, verbatim.
    let maps = grasp_maps(&[rect(60.0, 40.0, 0.0, 60.0, 20.0)], 80, 120).unwrap();
    let q = |r, c| maps.quality[at(&maps, r, c)];
    assert!(q(40, 60) == 1.0 && q(40, 69) == 1.0 && q(40, 51) == 1.0);
    assert!(
        q(40, 71) == 0.0 && q(40, 49) == 0.0,
        "centre third spans x in [50, 70]"
    );
    assert!(
        q(31, 60) == 1.0 && q(29, 60) == 0.0,
        "full jaw extent: y in [30, 50]"
    );
    let i = at(&maps, 40, 60);
    assert!((maps.cos2t[i] - 1.0).abs() < 1e-6 && maps.sin2t[i].abs() < 1e-6);
    assert!((maps.width[i] - 60.0 / WIDTH_SCALE_PX).abs() < 1e-6);
    assert_eq!(maps.quality.iter().sum::<f32>(), 21.0 * 21.0);
    for j in 0..maps.quality.len() {
        if maps.quality[j] == 0.0 {
            assert!(maps.width[j] == 0.0 && maps.cos2t[j] == 0.0 && maps.sin2t[j] == 0.0);
        }
    }
}

/// The rectangles of the reference case (train_ae's round-trip test plus one at 89.5°).
fn reference_truth() -> Vec<GraspRectangle> {
    vec![
        rect(25.0, 25.0, 0.0, 40.0, 20.0),
        rect(85.0, 30.0, 60.0, 36.0, 16.0),
        rect(30.0, 85.0, -89.0, 45.0, 24.0),
        rect(85.0, 85.0, -35.0, 60.0, 30.0),
        rect(55.0, 60.0, 89.5, 30.0, 14.0),
    ]
}

#[test]
fn maps_from_rectangles_decode_to_the_same_rectangles() {
    let truth = reference_truth();
    let maps = grasp_maps(&truth, 112, 112).unwrap();
    let params = GraspDecodeParams {
        num_grasps: 10,
        jaw_side_fraction: None,
        ..GraspDecodeParams::default()
    };
    let decoded = decode_grasps(maps.view(), &params).unwrap();
    assert_eq!(decoded.len(), truth.len(), "{decoded:?}");
    for t in &truth {
        let [tx, ty] = t.center();
        let d = decoded
            .iter()
            .min_by(|a, b| {
                let da = (a.center_px[0] - tx).hypot(a.center_px[1] - ty);
                let db = (b.center_px[0] - tx).hypot(b.center_px[1] - ty);
                da.total_cmp(&db)
            })
            .unwrap();
        assert!(
            (d.center_px[0] - tx).hypot(d.center_px[1] - ty) <= 1.0,
            "{d:?} vs {t:?}"
        );
        let da = angle_difference(d.angle, grasp_angle(t));
        assert!(da < 1f32.to_radians(), "{d:?} vs {t:?}");
        assert!((d.width_px - t.width_px()).abs() <= 1.0, "{d:?} vs {t:?}");
        assert!((d.jaw_px - d.width_px / 2.0).abs() < 1e-4);
        assert!((d.quality - 1.0).abs() < 0.3);
    }
}

#[test]
fn angles_across_plus_minus_ninety_degrees_round_trip() {
    for theta_deg in [
        89.9f32, 89.5, 88.0, 90.0, -89.5, -89.9, -88.0, 0.0, 45.0, -45.0,
    ] {
        let truth = rect(40.0, 40.0, theta_deg, 36.0, 18.0);
        let maps = grasp_maps(&[truth], 80, 80).unwrap();
        let d = decode_grasps(maps.view(), &GraspDecodeParams::default()).unwrap()[0];
        let err = angle_difference(d.angle, theta_deg.to_radians());
        assert!(err < 0.5f32.to_radians(), "θ = {theta_deg}°: decoded {d:?}");
        assert!((-std::f32::consts::FRAC_PI_2..std::f32::consts::FRAC_PI_2).contains(&d.angle));
    }
}

#[test]
fn angle_is_averaged_through_cos_and_sin_not_the_wrapped_angle() {
    // A grasp region whose columns alternate between θ = +88° and θ = −88°: both are 2° from
    // ±90°; the mean of the wrapped angles is near 0°, almost perpendicular to every label.
    let mut maps = GraspMaps::zeros(80, 80);
    let mut wrapped_sum = 0.0f32;
    for r in 33..=47 {
        for c in 33..=47 {
            let theta = if c % 2 == 0 { 88f32 } else { -88.0 }.to_radians();
            let i = at(&maps, r, c);
            maps.quality[i] = 1.0;
            maps.cos2t[i] = (2.0 * theta).cos();
            maps.sin2t[i] = (2.0 * theta).sin();
            maps.width[i] = 0.2;
            wrapped_sum += wrap_angle(theta);
        }
    }
    let naive = wrapped_sum / 225.0;
    assert!(
        naive.abs() < 10f32.to_radians(),
        "the naive mean is {}°",
        naive.to_degrees()
    );
    let d = decode_grasps(maps.view(), &GraspDecodeParams::default()).unwrap()[0];
    let err = angle_difference(d.angle, 90f32.to_radians());
    assert!(err < 1f32.to_radians(), "decoded {}°", d.angle.to_degrees());
}

#[test]
fn peaks_within_min_distance_of_a_better_one_are_suppressed() {
    let params = raw_params();
    let n = |spikes: &[(usize, usize, f32)], params: &GraspDecodeParams| {
        decode_grasps(with_spikes(120, 120, spikes).view(), params)
            .unwrap()
            .len()
    };
    // The window is a square of radius min_distance_px (20): Chebyshev distance ≤ 20.
    assert_eq!(n(&[(50, 50, 1.0), (50, 70, 0.5)], &params), 1);
    assert_eq!(n(&[(50, 50, 1.0), (50, 71, 0.5)], &params), 2);
    assert_eq!(
        n(&[(50, 50, 1.0), (70, 70, 0.5)], &params),
        1,
        "diagonal, 28 px away"
    );
    assert_eq!(n(&[(50, 50, 1.0), (71, 50, 0.5)], &params), 2);
    let close = GraspDecodeParams {
        min_distance_px: 5,
        ..params
    };
    assert_eq!(n(&[(50, 50, 1.0), (50, 55, 0.5)], &close), 1);
    assert_eq!(n(&[(50, 50, 1.0), (50, 56, 0.5)], &close), 2);
    // The better one survives.
    let g = decode_grasps(
        with_spikes(120, 120, &[(50, 60, 0.5), (50, 50, 1.0)]).view(),
        &params,
    )
    .unwrap();
    assert_eq!(centers(&g), vec![[50.0, 50.0]]);
}

#[test]
fn smoothed_grasps_closer_than_min_distance_count_once() {
    let params = GraspDecodeParams {
        num_grasps: 10,
        ..GraspDecodeParams::default()
    };
    for (gap, expected) in [(15.0, 1), (45.0, 2)] {
        let better = grasp_maps(&[rect(30.0, 50.0, 0.0, 36.0, 18.0)], 100, 100).unwrap();
        let worse = grasp_maps(&[rect(30.0 + gap, 50.0, 0.0, 36.0, 18.0)], 100, 100).unwrap();
        let mut maps = better.clone();
        for i in 0..maps.quality.len() {
            if maps.quality[i] == 0.0 && worse.quality[i] > 0.0 {
                maps.quality[i] = 0.7 * worse.quality[i];
                maps.cos2t[i] = worse.cos2t[i];
                maps.sin2t[i] = worse.sin2t[i];
                maps.width[i] = worse.width[i];
            }
        }
        let g = decode_grasps(maps.view(), &params).unwrap();
        assert_eq!(g.len(), expected, "gap {gap}: {g:?}");
        assert!(
            (g[0].center_px[0] - 30.0).abs() <= 1.0,
            "the better grasp first: {g:?}"
        );
        if expected == 2 {
            assert!((g[1].center_px[0] - 75.0).abs() <= 1.0 && g[1].quality < g[0].quality);
        }
    }
}

#[test]
fn quality_threshold_keeps_peaks_at_it_and_drops_those_below() {
    let maps = with_spikes(100, 100, &[(20, 20, 0.2), (70, 70, 0.19999)]);
    let g = decode_grasps(maps.view(), &raw_params()).unwrap();
    assert_eq!(centers(&g), vec![[20.0, 20.0]]);
    let lower = GraspDecodeParams {
        quality_threshold: 0.1,
        ..raw_params()
    };
    assert_eq!(decode_grasps(maps.view(), &lower).unwrap().len(), 2);
    // Smoothing spreads a lone spike below the default threshold; all-zero maps give nothing.
    let default = GraspDecodeParams::default();
    assert!(decode_grasps(maps.view(), &default).unwrap().is_empty());
    let zeros = GraspMaps::zeros(64, 64);
    assert!(decode_grasps(zeros.view(), &default).unwrap().is_empty());
}

#[test]
fn grasps_are_sorted_by_quality_then_row_then_column() {
    let spikes = [
        (70, 10, 0.9),
        (10, 70, 0.9),
        (70, 70, 0.9),
        (40, 40, 0.95),
        (10, 10, 0.9),
        (100, 100, 0.3),
    ];
    let maps = with_spikes(120, 120, &spikes);
    let g = decode_grasps(maps.view(), &raw_params()).unwrap();
    let expected = [
        [40.0, 40.0],
        [10.0, 10.0],
        [70.0, 10.0],
        [10.0, 70.0],
        [70.0, 70.0],
    ];
    let mut expected = expected.to_vec();
    expected.push([100.0, 100.0]);
    assert_eq!(centers(&g), expected, "x = column, y = row");
    // The same input in another order gives the same bytes.
    let mut reversed = spikes;
    reversed.reverse();
    let again = decode_grasps(with_spikes(120, 120, &reversed).view(), &raw_params()).unwrap();
    assert_eq!(g, again);
    // num_grasps keeps the best.
    let top2 = GraspDecodeParams {
        num_grasps: 2,
        ..raw_params()
    };
    assert_eq!(
        centers(&decode_grasps(maps.view(), &top2).unwrap()),
        expected[..2]
    );
}

#[test]
fn a_flat_top_is_one_grasp_at_its_mean_position() {
    let maps = with_spikes(60, 60, &[(30, 30, 0.8), (30, 31, 0.8), (31, 31, 0.8)]);
    let g = decode_grasps(maps.view(), &raw_params()).unwrap();
    assert_eq!(g.len(), 1);
    assert!((g[0].center_px[0] - 92.0 / 3.0).abs() < 1e-5);
    assert!((g[0].center_px[1] - 91.0 / 3.0).abs() < 1e-5);
}

#[test]
fn decoded_rectangle_has_train_ae_corners() {
    let g = DecodedGrasp {
        center_px: [50.0, 40.0],
        angle: 30f32.to_radians(),
        width_px: 40.0,
        jaw_px: 20.0,
        quality: 0.9,
    };
    let r = g.rectangle();
    let [p0, p1, p2, _] = r.corners_px;
    // First edge along (cos θ, −sin θ) on screen (y down).
    let (s, c) = g.angle.sin_cos();
    assert!((p1[0] - p0[0] - 40.0 * c).abs() < 1e-4 && (p1[1] - p0[1] + 40.0 * s).abs() < 1e-4);
    assert!((grasp_angle(&r) - g.angle).abs() < 1e-5);
    assert!((r.width_px() - 40.0).abs() < 1e-4 && (r.height_px() - 20.0).abs() < 1e-4);
    assert!(((p2[0] - p1[0]).hypot(p2[1] - p1[1]) - 20.0).abs() < 1e-4);
    assert_eq!(r.center(), [50.0, 40.0]);
}

fn camera() -> Intrinsics {
    Intrinsics {
        width: 640,
        height: 480,
        fx: 500.0,
        fy: 400.0,
        cx: 319.5,
        cy: 239.5,
    }
}

fn grasp(x: f32, y: f32, theta_deg: f32, width_px: f32) -> DecodedGrasp {
    DecodedGrasp {
        center_px: [x, y],
        angle: theta_deg.to_radians(),
        width_px,
        jaw_px: width_px / 2.0,
        quality: 0.8,
    }
}

fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
}

#[test]
fn pixel_to_camera_follows_the_pinhole_model() {
    let k = camera();
    let depth = vec![0.8f32; 640 * 480];
    let params = GraspDecodeParams::default();
    let g = grasp(400.0, 100.0, 0.0, 50.0);
    let p = grasp_pose(&g, &depth, &k, &InputCrop::IDENTITY, &params).unwrap();
    let expected = [
        (400.0 - 319.5) * 0.8 / 500.0,
        (100.0 - 239.5) * 0.8 / 400.0,
        0.8,
    ];
    assert!(close(p.position_m, expected, 1e-6), "{p:?}");
    assert_eq!(p.depth_m, 0.8);
    let n = expected.iter().map(|v| v * v).sum::<f32>().sqrt();
    assert!(close(p.approach, expected.map(|v| v / n), 1e-6));
    assert!(
        (p.opening_m - 50.0 * 0.8 / 500.0).abs() < 1e-6,
        "θ = 0 opens along x"
    );
    // Closing axis: image +x, made perpendicular to the ray.
    let a = p.approach;
    let x = [1.0 - a[0] * a[0], -a[0] * a[1], -a[0] * a[2]];
    let nx = x.iter().map(|v| v * v).sum::<f32>().sqrt();
    assert!(close(p.closing_axis, x.map(|v| v / nx), 1e-5), "{p:?}");
    assert_eq!(p.grasp, g);

    // θ = 90°: opening along image −y (up on screen), scaled by fy.
    let p = grasp_pose(
        &grasp(320.0, 240.0, 90.0, 50.0),
        &depth,
        &k,
        &InputCrop::IDENTITY,
        &params,
    )
    .unwrap();
    assert!((p.opening_m - 50.0 * 0.8 / 400.0).abs() < 1e-6);
    assert!(p.closing_axis[1] < -0.999, "{p:?}");

    // The gripper frame: origin at the grasp, z along the approach, right-handed.
    let t = p.camera_from_grasp();
    assert!(close(transform_point(&t, [0.0; 3]), p.position_m, 1e-7));
    assert!(close(rotate_vector(&t, [0.0, 0.0, 1.0]), p.approach, 1e-6));
    assert!(close(
        rotate_vector(&t, [1.0, 0.0, 0.0]),
        p.closing_axis,
        1e-6
    ));
    let det = t.rotation.matrix().determinant();
    assert!((det - 1.0).abs() < 1e-5);
}

#[test]
fn input_crop_maps_network_pixels_to_camera_pixels() {
    // train_ae's evaluation input for a 640×480 image: the centred 480×480 square at x0 = 80.
    let crop = InputCrop::centered_square(640, 480, 224);
    assert_eq!(crop, InputCrop::square(80, 0, 480, 224));
    let s = 480.0 / 224.0;
    assert!((crop.image_px_per_map_px - s).abs() < 1e-6);
    let centre = crop.image_from_map([111.5, 111.5]);
    assert!((centre[0] - 319.5).abs() < 1e-4 && (centre[1] - 239.5).abs() < 1e-4);
    let corner = crop.image_from_map([0.0, 0.0]);
    assert!((corner[0] - (0.5 * s - 0.5 + 80.0)).abs() < 1e-5);
    // A 112 px grasp in the map is 240 image pixels: 240 · z / fx metres.
    let k = camera();
    let depth = vec![0.6f32; 640 * 480];
    let params = GraspDecodeParams::default();
    let g = grasp(111.5, 111.5, 0.0, 112.0);
    let p = grasp_pose(&g, &depth, &k, &crop, &params).unwrap();
    assert!(close(p.position_m, [0.0, 0.0, 0.6], 1e-6), "{p:?}");
    assert!((p.opening_m - 240.0 * 0.6 / 500.0).abs() < 1e-5);
    // Odd margins round half to even, as Python's round().
    assert_eq!(InputCrop::centered_square(641, 480, 224).x0_px, 80.0);
    assert_eq!(InputCrop::centered_square(643, 480, 224).x0_px, 82.0);
    assert_eq!(InputCrop::centered_square(480, 640, 224).y0_px, 80.0);
}

#[test]
fn depth_is_the_median_of_valid_pixels_in_the_window() {
    let k = camera();
    let params = GraspDecodeParams::default();
    let g = grasp(100.0, 50.0, 0.0, 30.0);
    let idx = |x: usize, y: usize| y * 640 + x;
    let mut depth = vec![0.8f32; 640 * 480];
    for (i, bad) in [f32::NAN, 0.0, -1.0, f32::INFINITY, 3.0, 3.0, 0.01]
        .into_iter()
        .enumerate()
    {
        depth[idx(98 + i % 5, 48 + i / 5)] = bad;
    }
    let p = grasp_pose(&g, &depth, &k, &InputCrop::IDENTITY, &params).unwrap();
    assert_eq!(p.depth_m, 0.8);
    assert!((p.position_m[2] - 0.8).abs() < 1e-7);
    // Only four valid pixels in the 5×5 window: the mean of the middle two.
    let mut depth = vec![0.0f32; 640 * 480];
    for (x, z) in [(98, 0.5), (99, 0.9), (101, 0.6), (102, 0.7)] {
        depth[idx(x, 52)] = z;
    }
    depth[idx(103, 50)] = 5.0; // outside the window
    let p = grasp_pose(&g, &depth, &k, &InputCrop::IDENTITY, &params).unwrap();
    assert!((p.depth_m - 0.65).abs() < 1e-6);
    // None valid: an error, not a point at depth 0.
    let wider = GraspDecodeParams {
        depth_radius_px: 3,
        ..params
    };
    let mut depth = vec![f32::NAN; 640 * 480];
    depth[idx(103, 50)] = 0.9;
    assert!(matches!(
        grasp_pose(&g, &depth, &k, &InputCrop::IDENTITY, &params),
        Err(GraspDecodeError::NoDepth { radius_px: 2, .. })
    ));
    let p = grasp_pose(&g, &depth, &k, &InputCrop::IDENTITY, &wider).unwrap();
    assert_eq!(p.depth_m, 0.9);
}

#[test]
fn maps_of_different_sizes_are_an_error_naming_the_map() {
    let maps = GraspMaps::zeros(10, 12);
    let short = vec![0.0f32; 119];
    let mut view = maps.view();
    view.sin2t = &short;
    let e = decode_grasps(view, &GraspDecodeParams::default()).unwrap_err();
    assert_eq!(
        e,
        GraspDecodeError::MapSize {
            map: "sin2t",
            len: 119,
            rows: 10,
            cols: 12
        }
    );
    assert!(e.to_string().contains("sin2t"), "{e}");
}

#[test]
fn non_finite_map_values_are_an_error_with_their_position() {
    for (map, value) in [(0, f32::NAN), (1, f32::INFINITY), (3, f32::NEG_INFINITY)] {
        let mut maps = GraspMaps::zeros(10, 12);
        let i = 3 * 12 + 7;
        [
            &mut maps.quality,
            &mut maps.cos2t,
            &mut maps.sin2t,
            &mut maps.width,
        ][map][i] = value;
        let e = decode_grasps(maps.view(), &GraspDecodeParams::default()).unwrap_err();
        let name = ["quality", "cos2t", "sin2t", "width"][map];
        assert!(
            matches!(e, GraspDecodeError::NonFinite { map: m, row: 3, col: 7, .. } if m == name),
            "{e:?}"
        );
    }
}

#[test]
fn empty_maps_are_an_error() {
    for (rows, cols) in [(0, 0), (0, 5), (5, 0)] {
        let maps = GraspMaps::zeros(rows, cols);
        let e = decode_grasps(maps.view(), &GraspDecodeParams::default()).unwrap_err();
        assert_eq!(e, GraspDecodeError::EmptyMaps { rows, cols });
        assert_eq!(
            grasp_maps(&[], rows, cols).unwrap_err(),
            GraspDecodeError::EmptyMaps { rows, cols }
        );
    }
    let overflow = GraspMaps {
        rows: usize::MAX,
        cols: 2,
        ..GraspMaps::zeros(0, 0)
    };
    assert!(matches!(
        decode_grasps(overflow.view(), &GraspDecodeParams::default()),
        Err(GraspDecodeError::EmptyMaps { .. })
    ));
}

#[test]
fn invalid_params_are_an_error_naming_the_field() {
    let d = GraspDecodeParams::default();
    assert_eq!(d.validate(), Ok(()));
    let cases = [
        (GraspDecodeParams { num_grasps: 0, ..d }, "num_grasps"),
        (
            GraspDecodeParams {
                quality_threshold: f32::NAN,
                ..d
            },
            "quality_threshold",
        ),
        (
            GraspDecodeParams {
                quality_sigma_px: -1.0,
                ..d
            },
            "quality_sigma_px",
        ),
        (
            GraspDecodeParams {
                width_sigma_px: 1000.0,
                ..d
            },
            "width_sigma_px",
        ),
        (
            GraspDecodeParams {
                jaw_side_fraction: Some(0.0),
                ..d
            },
            "jaw_side_fraction",
        ),
    ];
    let maps = GraspMaps::zeros(8, 8);
    for (params, name) in cases {
        let e = decode_grasps(maps.view(), &params).unwrap_err();
        assert!(
            matches!(e, GraspDecodeError::InvalidParam { field, .. } if field == name),
            "{e:?}"
        );
        assert!(e.to_string().contains(name), "{e}");
    }
}

#[test]
fn rasterising_a_non_finite_rectangle_is_an_error() {
    let mut bad = rect(10.0, 10.0, 0.0, 8.0, 4.0);
    bad.corners_px[2][1] = f32::NAN;
    let good = rect(20.0, 20.0, 0.0, 8.0, 4.0);
    assert_eq!(
        grasp_maps(&[good, bad], 32, 32).unwrap_err(),
        GraspDecodeError::InvalidRectangle { index: 1 }
    );
    // Rectangles partly or wholly outside the maps are clipped, not errors.
    let maps = grasp_maps(
        &[
            rect(-5.0, 16.0, 0.0, 40.0, 10.0),
            rect(500.0, 9.0, 0.0, 8.0, 4.0),
        ],
        32,
        32,
    )
    .unwrap();
    assert!(maps.quality.contains(&1.0));
}

#[test]
fn bad_pose_input_is_an_error() {
    let k = camera();
    let depth = vec![0.8f32; 640 * 480];
    let params = GraspDecodeParams::default();
    let id = InputCrop::IDENTITY;
    let g = grasp(100.0, 50.0, 0.0, 30.0);
    assert_eq!(
        grasp_pose(&g, &depth[1..], &k, &id, &params).unwrap_err(),
        GraspDecodeError::DepthSize {
            len: 640 * 480 - 1,
            width: 640,
            height: 480
        }
    );
    for outside in [grasp(-1.0, 50.0, 0.0, 30.0), grasp(100.0, 479.6, 0.0, 30.0)] {
        assert!(matches!(
            grasp_pose(&outside, &depth, &k, &id, &params),
            Err(GraspDecodeError::OutsideImage { .. })
        ));
    }
    let nan = grasp(f32::NAN, 50.0, 0.0, 30.0);
    assert_eq!(
        grasp_pose(&nan, &depth, &k, &id, &params).unwrap_err(),
        GraspDecodeError::InvalidGrasp { field: "center_px" }
    );
    let flat = Intrinsics { fx: 0.0, ..k };
    assert!(matches!(
        grasp_pose(&g, &depth, &flat, &id, &params),
        Err(GraspDecodeError::InvalidIntrinsics { .. })
    ));
    let zero_input = InputCrop::square(0, 0, 480, 0);
    assert!(matches!(
        grasp_pose(&g, &depth, &k, &zero_input, &params),
        Err(GraspDecodeError::InvalidCrop {
            field: "image_px_per_map_px",
            ..
        })
    ));
    let bad_params = GraspDecodeParams {
        jaw_side_fraction: Some(f32::NAN),
        ..params
    };
    assert!(matches!(
        grasp_pose(&g, &depth, &k, &id, &bad_params),
        Err(GraspDecodeError::InvalidParam {
            field: "jaw_side_fraction",
            ..
        })
    ));
}

#[test]
fn params_deserialize_with_documented_defaults() {
    let p: GraspDecodeParams = serde_json::from_str(r#"{"num_grasps": 5}"#).unwrap();
    assert_eq!(
        p,
        GraspDecodeParams {
            num_grasps: 5,
            ..GraspDecodeParams::default()
        }
    );
    let d = GraspDecodeParams::default();
    assert_eq!(
        (d.num_grasps, d.quality_threshold, d.min_distance_px),
        (1, 0.2, 20)
    );
    assert_eq!(
        (
            d.quality_sigma_px,
            d.width_sigma_px,
            d.jaw_side_fraction,
            d.depth_radius_px
        ),
        (2.0, 1.0, Some(0.02 / 0.22), 2)
    );
    assert!(serde_json::from_str::<GraspDecodeParams>(r#"{"threshold": 0.3}"#).is_err());
}
