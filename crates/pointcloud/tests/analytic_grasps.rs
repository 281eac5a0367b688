//! The analytic grasp source, seeing only a depth crop, proposes grasps that the mesh-based
//! geometric labeller accepts: its best grasp on seeded scenes of every procedural category,
//! its rim pinches on bowls and mugs; nothing on a box wider than the gripper or an empty
//! table; a typed error naming the problem on bad input; the same grasps, bit for bit, for the
//! same input.

use std::time::Instant;

use lgdm_pointcloud::crop::{CropSpec, FoundObject, crop_largest_object};
use lgdm_pointcloud::grasp::analytic::{
    AnalyticError, AnalyticGrasp, AnalyticParams, analytic_grasps, analytic_grasps_detailed,
    check_proposals,
};
use lgdm_pointcloud::grasp::cornell::table_mesh;
use lgdm_pointcloud::grasp::decode::{DecodedGrasp, GraspDecodeParams, grasp_pose};
use lgdm_pointcloud::grasp::{GraspScene, GraspSpec, GraspVerdict, evaluate_grasp, grasp_scene};
use lgdm_pointcloud::math::{Pose, look_at, normalize, rotate_vector, transform_point};
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::objects::{CATEGORIES, ObjectModel, procedural_object};
use lgdm_pointcloud::render::{Camera, Intrinsics, RenderItem, render};
use lgdm_pointcloud::segment::SegmentParams;

/// Scenes of the agreement test: 12 per category, instances 0–4, scene and object seed 0.
/// (The parameters were tuned on scene and object seed 1000, never on these.)
const AGREEMENT_SCENES: usize = 120;

fn object(category: &str, instance: usize, seed: u64) -> ObjectModel {
    ObjectModel {
        name: format!("{category}_{instance:02}"),
        category: category.to_string(),
        mesh: procedural_object(category, instance, seed).unwrap(),
        physics: Default::default(),
        parts: Vec::new(),
    }
}

fn crop_of(scene: &GraspScene) -> FoundObject {
    crop_largest_object(
        &scene.frame,
        &scene.camera.intrinsics,
        &SegmentParams::default(),
        &CropSpec::default(),
    )
    .unwrap()
}

/// The labeller's verdict on a grasp placed as the robot places it: the crop pixel through the
/// crop's window into the frame, back-projected with the frame's depth (`grasp_pose`), into
/// the world; the opening axis from the image angle, made horizontal.
fn judge(
    scene: &GraspScene,
    found: &FoundObject,
    object: &ObjectModel,
    g: &AnalyticGrasp,
) -> GraspVerdict {
    let pose = grasp_pose(
        &g.grasp,
        &scene.frame.depth_m,
        &scene.camera.intrinsics,
        &found.crop.window,
        &GraspDecodeParams::default(),
    )
    .unwrap();
    let world_from_camera = scene.camera.world_from_camera;
    let centre_top = transform_point(&world_from_camera, pose.position_m);
    let a = rotate_vector(&world_from_camera, pose.closing_axis);
    let axis = normalize([a[0], a[1], 0.0]);
    let mesh_world = object.mesh.transformed(&scene.world_from_object);
    evaluate_grasp(&mesh_world, centre_top, axis, &GraspSpec::default()).0
}

#[test]
fn top1_agrees_with_the_geometric_labeller() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    // Per category: scenes, top-1 accepted, no grasp where the labeller found none either,
    // scenes with a grasp.
    let mut per_category = [[0usize; 4]; 10];
    // Top-1 [safe, not safe] × [scenes, accepted].
    let mut tiers = [[0usize; 2]; 2];
    let mut seconds = 0.0f64;
    for k in 0..AGREEMENT_SCENES {
        let c = k % CATEGORIES.len();
        let object = object(CATEGORIES[c], (k / CATEGORIES.len()) % 5, 0);
        let scene = grasp_scene(&spec, 0, k, &object);
        let found = crop_of(&scene);
        let start = Instant::now();
        let grasps =
            analytic_grasps_detailed(&found.crop, &scene.camera.intrinsics, &spec, &params)
                .unwrap();
        seconds += start.elapsed().as_secs_f64();
        let row = &mut per_category[c];
        row[0] += 1;
        match grasps.first() {
            Some(best) => {
                row[3] += 1;
                let verdict = judge(&scene, &found, &object, best);
                let tier = &mut tiers[usize::from(!best.safe)];
                tier[0] += 1;
                tier[1] += usize::from(verdict == GraspVerdict::Accepted);
                if verdict == GraspVerdict::Accepted {
                    row[1] += 1;
                } else {
                    println!("scene {k} ({}): top-1 rejected: {verdict:?}", object.name);
                }
            }
            None if scene.positives().is_empty() => row[2] += 1,
            None => println!(
                "scene {k} ({}): no grasp, the labeller has some",
                object.name
            ),
        }
    }
    let mut total = [0usize; 4];
    for (c, row) in per_category.iter().enumerate() {
        println!(
            "{:>10}: top-1 accepted {:>2}/{:>2}, no grasp where the labeller has none {}, scenes with a grasp {}",
            CATEGORIES[c], row[1], row[0], row[2], row[3]
        );
        for (t, v) in total.iter_mut().zip(row) {
            *t += v;
        }
    }
    let rate = |n: usize, d: usize| n as f64 / d.max(1) as f64;
    let accepted = rate(total[1], total[0]);
    let agreement = rate(total[1] + total[2], total[0]);
    let precision = rate(total[1], total[3]);
    println!(
        "top-1 accepted {}/{} = {:.1} %; agreement (or both find none) {:.1} %; accepted when a \
         grasp is returned {:.1} %; {:.1} ms per crop (release)",
        total[1],
        total[0],
        100.0 * accepted,
        100.0 * agreement,
        100.0 * precision,
        1e3 * seconds / AGREEMENT_SCENES as f64
    );
    println!(
        "safe top-1 accepted {}/{}, other top-1 accepted {}/{}",
        tiers[0][1], tiers[0][0], tiers[1][1], tiers[1][0]
    );
    // Measured (scene and object seed 0, 120 scenes): 83.3 % accepted, 85.0 % agreement,
    // 88.5 % accepted when a grasp is returned, 94.7 % (90/95) when it is safe.
    let safe = rate(tiers[0][1], tiers[0][0]);
    assert!(safe >= 0.90, "safe top-1 accepted {safe:.3}");
    assert!(accepted >= 0.80, "top-1 accepted {accepted:.3}");
    assert!(agreement >= 0.82, "agreement {agreement:.3}");
    assert!(precision >= 0.85, "precision {precision:.3}");
}

#[test]
fn bowls_and_mugs_get_rim_pinches_the_labeller_accepts() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    let (mut pinches, mut accepted) = (0usize, 0usize);
    for category in ["bowl", "mug"] {
        for instance in 0..5 {
            let object = object(category, instance, 0);
            let scene = grasp_scene(&spec, 7, instance, &object);
            let found = crop_of(&scene);
            let grasps =
                analytic_grasps_detailed(&found.crop, &scene.camera.intrinsics, &spec, &params)
                    .unwrap();
            let rims: Vec<&AnalyticGrasp> =
                grasps.iter().filter(|g| g.opening_m <= 0.025).collect();
            assert!(
                !rims.is_empty(),
                "{}: no rim pinch among {} grasps",
                object.name,
                grasps.len()
            );
            let ok = rims
                .iter()
                .filter(|g| judge(&scene, &found, &object, g) == GraspVerdict::Accepted)
                .count();
            println!("{}: {ok}/{} rim pinches accepted", object.name, rims.len());
            assert!(ok >= 1, "{}: no rim pinch accepted", object.name);
            pinches += rims.len();
            accepted += ok;
        }
    }
    assert!(
        accepted as f64 >= 0.8 * pinches as f64,
        "{accepted}/{pinches} rim pinches accepted"
    );
}

/// A frame of `mesh` standing on the table under a top-down camera 0.5 m up.
fn top_down(mesh: Option<&Mesh>) -> (Camera, FoundObject) {
    let camera = Camera::new(
        Intrinsics::kinect_vga(),
        look_at([0.0, 0.0, 0.5], [0.0; 3], [0.0, 1.0, 0.0]),
    );
    let table = table_mesh();
    let mut items = vec![RenderItem {
        mesh: &table,
        world_from_object: Pose::identity(),
        label: 1,
    }];
    if let Some(mesh) = mesh {
        items.push(RenderItem {
            mesh,
            world_from_object: Pose::identity(),
            label: 2,
        });
    }
    let frame = render(&camera, &items);
    let found = crop_largest_object(
        &frame,
        &camera.intrinsics,
        &SegmentParams::default(),
        &CropSpec::default(),
    )
    .unwrap();
    (camera, found)
}

#[test]
fn a_box_wider_than_the_gripper_and_an_empty_table_give_no_grasp() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    // 12 cm × 11 cm × 6 cm: wider than the 8.5 cm opening in every direction.
    let wide = Mesh::cuboid([0.0, 0.0, 0.03], [0.12, 0.11, 0.06], [200, 60, 60]);
    let (camera, found) = top_down(Some(&wide));
    assert!(found.object.is_some());
    let grasps = analytic_grasps(&found.crop, &camera.intrinsics, &spec, &params).unwrap();
    assert!(grasps.is_empty(), "{grasps:?}");
    // The same box 6 cm deep is grasped across its depth.
    let narrow = Mesh::cuboid([0.0, 0.0, 0.03], [0.12, 0.06, 0.06], [200, 60, 60]);
    let (camera, found) = top_down(Some(&narrow));
    let grasps = analytic_grasps_detailed(&found.crop, &camera.intrinsics, &spec, &params).unwrap();
    let best = grasps.first().expect("a grasp across the 6 cm side");
    assert!((best.opening_m - 0.06).abs() < 0.003, "{best:?}");
    // Image y is world −y here: across the depth is θ = ±90°.
    assert!(best.grasp.angle.abs() > 80f32.to_radians(), "{best:?}");
    // The empty table.
    let (camera, found) = top_down(None);
    assert!(found.object.is_none());
    let grasps = analytic_grasps(&found.crop, &camera.intrinsics, &spec, &params).unwrap();
    assert!(grasps.is_empty(), "{grasps:?}");
}

#[test]
fn grasps_follow_the_decoded_grasp_conventions() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    let can = procedural_object("can", 1, 0).unwrap();
    let (camera, found) = top_down(Some(&can));
    let grasps = analytic_grasps(&found.crop, &camera.intrinsics, &spec, &params).unwrap();
    assert!(!grasps.is_empty() && grasps.len() <= params.num_grasps);
    let crop_spec = CropSpec::default();
    let jaw_px = crop_spec.size_px as f32 * crop_spec.side_fraction(spec.finger_width_m);
    for pair in grasps.windows(2) {
        assert!(pair[0].quality >= pair[1].quality, "best first");
    }
    for g in &grasps {
        let half_pi = std::f32::consts::FRAC_PI_2;
        assert!((-half_pi..half_pi).contains(&g.angle), "{g:?}");
        assert!(g.quality > 0.0 && g.quality <= 1.0, "{g:?}");
        assert!((g.jaw_px - jaw_px).abs() < 0.05, "{g:?} vs {jaw_px}");
        assert!(g.width_px > 0.0, "{g:?}");
        let c = g.center_px;
        assert!(
            (0.0..224.0).contains(&c[0]) && (0.0..224.0).contains(&c[1]),
            "{g:?}"
        );
    }
    // Near-duplicates are suppressed: no two grasps within 6 mm (≈ 6 px) and 15°.
    for (i, a) in grasps.iter().enumerate() {
        for b in &grasps[i + 1..] {
            let d = (a.center_px[0] - b.center_px[0]).hypot(a.center_px[1] - b.center_px[1]);
            let da = lgdm_pointcloud::grasp::decode::angle_difference(a.angle, b.angle);
            assert!(d >= 5.0 || da > 14f32.to_radians(), "{a:?} {b:?}");
        }
    }
}

#[test]
fn bad_input_is_an_error_naming_the_problem() {
    let spec = GraspSpec::default();
    let can = procedural_object("can", 0, 0).unwrap();
    let (camera, found) = top_down(Some(&can));
    let k = camera.intrinsics;
    let field = |params: AnalyticParams| match analytic_grasps(&found.crop, &k, &spec, &params) {
        Err(AnalyticError::InvalidParam { field, .. }) => field,
        other => panic!("expected an invalid parameter, got {other:?}"),
    };
    let p = AnalyticParams::default();
    assert_eq!(field(AnalyticParams { num_grasps: 0, ..p }), "num_grasps");
    assert_eq!(
        field(AnalyticParams {
            cell_m: f32::NAN,
            ..p
        }),
        "cell_m"
    );
    assert_eq!(
        field(AnalyticParams {
            grid_step_m: f32::INFINITY,
            ..p
        }),
        "grid_step_m"
    );
    assert_eq!(field(AnalyticParams { num_angles: 0, ..p }), "num_angles");
    assert_eq!(
        field(AnalyticParams {
            min_height_m: -0.01,
            ..p
        }),
        "min_height_m"
    );
    assert_eq!(
        field(AnalyticParams {
            friction_cone_fraction: f32::NAN,
            ..p
        }),
        "friction_cone_fraction"
    );
    assert_eq!(
        field(AnalyticParams {
            safe_lane_tolerance_m: 0.005,
            ..p
        }),
        "safe_lane_tolerance_m"
    );
    // A gripper that cannot open.
    let bad_gripper = GraspSpec {
        max_opening_m: f32::NAN,
        ..spec
    };
    assert!(matches!(
        analytic_grasps(&found.crop, &k, &bad_gripper, &p),
        Err(AnalyticError::InvalidGripper(_))
    ));
    // Buffers of the wrong size.
    let mut short = found.crop.clone();
    short.depth_m.pop();
    assert!(matches!(
        analytic_grasps(&short, &k, &spec, &p),
        Err(AnalyticError::CropSize {
            buffer: "depth_m",
            ..
        })
    ));
    let mut short = found.crop.clone();
    short.rgb.truncate(10);
    assert!(matches!(
        analytic_grasps(&short, &k, &spec, &p),
        Err(AnalyticError::CropSize { buffer: "rgb", .. })
    ));
    // A crop without a table depth or window scale, and a camera without a focal length.
    let mut no_table = found.crop.clone();
    no_table.table_depth_m = f32::NAN;
    assert!(matches!(
        analytic_grasps(&no_table, &k, &spec, &p),
        Err(AnalyticError::InvalidCrop {
            field: "table_depth_m",
            ..
        })
    ));
    let mut no_scale = found.crop.clone();
    no_scale.window.image_px_per_map_px = 0.0;
    assert!(matches!(
        analytic_grasps(&no_scale, &k, &spec, &p),
        Err(AnalyticError::InvalidCrop {
            field: "window.image_px_per_map_px",
            ..
        })
    ));
    let blind = Intrinsics { fx: 0.0, ..k };
    assert!(matches!(
        analytic_grasps(&found.crop, &blind, &spec, &p),
        Err(AnalyticError::InvalidIntrinsics { .. })
    ));
    // Missing and non-finite depth is no data, not an error.
    let mut holes = found.crop.clone();
    for (i, d) in holes.depth_m.iter_mut().enumerate() {
        if i % 7 == 0 {
            *d = f32::NAN;
        } else if i % 11 == 0 {
            *d = -1.0;
        }
    }
    assert!(analytic_grasps(&holes, &k, &spec, &p).is_ok());
    let mut nothing = found.crop.clone();
    nothing.depth_m.iter_mut().for_each(|d| *d = 0.0);
    assert_eq!(analytic_grasps(&nothing, &k, &spec, &p).unwrap(), vec![]);
}

#[test]
fn same_input_gives_bit_identical_grasps() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    let bits = |grasps: &[AnalyticGrasp]| -> Vec<u32> {
        grasps
            .iter()
            .flat_map(|g| {
                let d = g.grasp;
                [
                    d.center_px[0],
                    d.center_px[1],
                    d.angle,
                    d.width_px,
                    d.jaw_px,
                    d.quality,
                    g.opening_m,
                    g.grasp_height_m,
                ]
            })
            .map(f32::to_bits)
            .collect()
    };
    for (category, k) in [("mug", 3), ("teapot", 4)] {
        let object = object(category, 1, 0);
        let scene = grasp_scene(&spec, 3, k, &object);
        let found = crop_of(&scene);
        let k = scene.camera.intrinsics;
        let first = analytic_grasps_detailed(&found.crop, &k, &spec, &params).unwrap();
        let again = analytic_grasps_detailed(&found.crop.clone(), &k, &spec, &params).unwrap();
        assert!(!first.is_empty());
        assert_eq!(bits(&first), bits(&again), "{category}");
    }
}

#[test]
fn another_sources_proposals_are_checked_and_refined_at_their_own_centre_and_axis() {
    let spec = GraspSpec::default();
    let params = AnalyticParams::default();
    // 12 cm × 6 cm × 6 cm: graspable across its 6 cm depth (image y), not along its length.
    let narrow = Mesh::cuboid([0.0, 0.0, 0.03], [0.12, 0.06, 0.06], [200, 60, 60]);
    let (camera, found) = top_down(Some(&narrow));
    let c = (found.crop.size_px as f32 - 1.0) / 2.0;
    let proposal = |dx: f32, dy: f32, angle_deg: f32, width_px: f32| DecodedGrasp {
        center_px: [c + dx, c + dy],
        angle: angle_deg.to_radians(),
        width_px,
        jaw_px: 20.0,
        quality: 0.7,
    };
    let proposals = [
        proposal(0.0, 0.0, 90.0, 40.0),  // across the depth: holds
        proposal(0.0, 0.0, 0.0, 80.0),   // along the 12 cm length: wider than the stroke
        proposal(30.0, 9.0, 84.0, 90.0), // across, off-centre and a little skewed
    ];
    let checked = check_proposals(
        &found.crop,
        &camera.intrinsics,
        &spec,
        &params,
        &proposals,
        false,
    )
    .unwrap();
    assert_eq!(checked.len(), 3);
    assert_eq!(checked[0], Some(proposals[0]), "unchanged when it passes");
    assert_eq!(checked[1], None, "the long axis is refused");
    assert!(checked[2].is_some(), "{checked:?}");
    let refined = check_proposals(
        &found.crop,
        &camera.intrinsics,
        &spec,
        &params,
        &proposals,
        true,
    )
    .unwrap();
    assert_eq!(refined[1], None);
    // The analytic source's own grasp across the box: its opening is the box's 6 cm depth.
    let own = analytic_grasps_detailed(&found.crop, &camera.intrinsics, &spec, &params).unwrap()[0];
    assert!((own.opening_m - 0.06).abs() < 0.003, "{own:?}");
    for g in [refined[0].unwrap(), refined[2].unwrap()] {
        // Moved onto the box's long axis, squared to its walls, opened as the analytic source
        // opens across the box, the proposal's quality (rank) kept.
        assert!((g.center_px[1] - c).abs() < 3.0, "{g:?}");
        assert!(g.angle.abs() > 88f32.to_radians(), "{g:?}");
        assert!(
            (g.width_px - own.grasp.width_px).abs() < 2.0,
            "{g:?} {own:?}"
        );
        assert_eq!(g.quality, 0.7);
    }
    // The off-centre one stays within the neighbourhood searched (6 mm ≈ 7 px at the box's
    // top) of where it was along the box.
    let along = refined[2].unwrap().center_px[0] - (c + 30.0);
    assert!(along.abs() <= 8.0, "{along}");
    // Nothing to check against: every proposal fails.
    let (camera, empty) = top_down(None);
    let none = check_proposals(
        &empty.crop,
        &camera.intrinsics,
        &spec,
        &params,
        &proposals,
        true,
    )
    .unwrap();
    assert_eq!(none, vec![None; 3]);
}
