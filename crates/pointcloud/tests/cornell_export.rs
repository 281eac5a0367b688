//! The Cornell export re-reads to the same rectangles; images have the Cornell layout (RGB PNG,
//! float32 depth TIFF in metres); positives are antipodal grasps within the gripper's opening.
//! By default the images are the object-centred crops (224 px, 0.22 m) with every rectangle's
//! jaw the finger width; `grasp_crop: None` writes whole frames with the labels as computed.

use lgdm_pointcloud::crop::crop_largest_object;
use lgdm_pointcloud::dataset::{DatasetSpec, generate, load_objects, standard_collections};
use lgdm_pointcloud::grasp::cornell::{
    CornellError, GraspIndex, INDEX_FORMAT, cornell_prefix, grasp_scene, read_rectangles,
    rectangles_in_crop, write_rectangles,
};
use lgdm_pointcloud::grasp::{GraspRectangle, GraspVerdict};
use lgdm_pointcloud::image::{RgbImage, read_depth_tiff};
use lgdm_pointcloud::segment::SegmentParams;

fn spec() -> DatasetSpec {
    let mut spec = DatasetSpec::small(3);
    spec.categories = vec!["mug".into(), "can".into(), "cereal_box".into()];
    spec.instances_per_category = 1;
    spec.collections = standard_collections().into_iter().take(1).collect();
    spec.frames_per_sequence = 1;
    spec.grasp_images = 3;
    spec
}

#[test]
fn crops_reread_to_the_labels_in_crop_pixels_with_the_finger_width_jaw() {
    let dir = tempfile::tempdir().unwrap();
    let spec = spec();
    let crop = spec.grasp_crop.expect("crops by default");
    let manifest = generate(&spec, dir.path(), &mut |_| {}).unwrap();
    let grasp = manifest.grasp.as_ref().unwrap();
    let index: GraspIndex =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(&grasp.index)).unwrap())
            .unwrap();
    assert_eq!(index.format, INDEX_FORMAT);
    assert_eq!(index.crop, Some(crop));
    let jaw_px = index.jaw_side_fraction.unwrap() * crop.size_px as f32;
    assert!((jaw_px - 0.02 / 0.22 * 224.0).abs() < 1e-3);
    let (objects, _, _) = load_objects(&spec).unwrap();
    let root = dir.path().join(&grasp.dir);
    let mut total_positives = 0;
    for (k, info) in index.images.iter().enumerate() {
        assert_eq!(info.category_name, spec.categories[info.category as usize]);
        let file = |s: &str| {
            std::path::PathBuf::from(format!(
                "{}{s}",
                cornell_prefix(&root, info.number).display()
            ))
        };
        let scene = grasp_scene(&spec.grasp, spec.seed, k, &objects[info.instance as usize]);
        let found = crop_largest_object(
            &scene.frame,
            &scene.camera.intrinsics,
            &SegmentParams::whole_components(),
            &crop,
        )
        .unwrap();
        assert_eq!(info.window, Some(found.crop.window));
        let pos = read_rectangles(&file("cpos.txt")).unwrap();
        assert_eq!(
            pos,
            rectangles_in_crop(&scene.positives(), &found.crop, jaw_px)
        );
        assert_eq!(pos.len(), info.positives);
        for r in &pos {
            assert!(
                (r.height_px() - jaw_px).abs() < 1e-3,
                "jaw {}",
                r.height_px()
            );
            let [x, y] = r.center();
            assert!((-0.5..223.5).contains(&x) && (-0.5..223.5).contains(&y));
        }
        total_positives += pos.len();
        let rgb = RgbImage::read_png(&file("r.png")).unwrap();
        assert_eq!((rgb.width, rgb.height), (224, 224));
        let (w, h, depth) = read_depth_tiff(&file("d.tiff")).unwrap();
        assert_eq!((w, h), (224, 224));
        assert_eq!(depth, found.crop.depth_m);
    }
    assert!(total_positives >= 10, "only {total_positives} positives");
}

#[test]
fn export_rereads_to_the_same_rectangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = spec();
    spec.grasp_crop = None;
    let manifest = generate(&spec, dir.path(), &mut |_| {}).unwrap();
    let grasp = manifest.grasp.as_ref().unwrap();
    assert_eq!(grasp.images, 3);
    let index: GraspIndex =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(&grasp.index)).unwrap())
            .unwrap();
    assert_eq!((index.crop, index.jaw_side_fraction), (None, None));
    let index = index.images;
    let (objects, _, _) = load_objects(&spec).unwrap();
    let root = dir.path().join(&grasp.dir);
    let mut total_positives = 0;
    for (k, info) in index.iter().enumerate() {
        assert_eq!(info.number, 100 + k);
        let prefix = cornell_prefix(&root, info.number);
        assert!(prefix.starts_with(root.join("01")));
        let file = |s: &str| std::path::PathBuf::from(format!("{}{s}", prefix.display()));
        // Same scene, recomputed: identical rectangles after the text round trip.
        let scene = grasp_scene(&spec.grasp, spec.seed, k, &objects[info.instance as usize]);
        assert_eq!(
            read_rectangles(&file("cpos.txt")).unwrap(),
            scene.positives()
        );
        assert_eq!(
            read_rectangles(&file("cneg.txt")).unwrap(),
            scene.negatives()
        );
        assert_eq!(scene.positives().len(), info.positives);
        total_positives += info.positives;
        // Images: 640×480 RGB and float32 depth equal to the rendered depth.
        let rgb = RgbImage::read_png(&file("r.png")).unwrap();
        assert_eq!((rgb.width, rgb.height), (640, 480));
        let (w, h, depth) = read_depth_tiff(&file("d.tiff")).unwrap();
        assert_eq!((w, h), (640, 480));
        assert_eq!(depth, scene.frame.depth_m);
        assert!(
            depth.iter().all(|&d| d > 0.05 && d < 1.0),
            "depth in metres, table everywhere"
        );
        // Every positive is an antipodal grasp the gripper can make.
        for c in scene
            .candidates
            .iter()
            .filter(|c| c.verdict == GraspVerdict::Accepted)
        {
            assert!(
                c.opening_m > 0.0
                    && c.opening_m + 2.0 * spec.grasp.clearance_m
                        <= spec.grasp.max_opening_m + 1e-6
            );
            let r = c.rectangle;
            assert!(r.width_px() > r.height_px() * 0.2);
        }
    }
    assert!(
        total_positives >= 10,
        "only {total_positives} positive grasps over 3 images"
    );
}

#[test]
fn rectangle_text_round_trip_and_bad_text() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pcd0100cpos.txt");
    let rects = vec![
        GraspRectangle::from_center([100.25, 200.5], 0.3, 41.7, 19.1),
        GraspRectangle::from_center([320.0, 240.0], -1.2, 12.0, 8.0),
    ];
    write_rectangles(&path, &rects).unwrap();
    assert_eq!(read_rectangles(&path).unwrap(), rects);
    for bad in [
        "1 2\n3 4\n5 6\n",
        "1 2\n3 x\n5 6\n7 8\n",
        "1 2 3\n",
        "NaN 1\n2 3\n4 5\n6 7\n",
    ] {
        std::fs::write(&path, bad).unwrap();
        assert!(
            matches!(read_rectangles(&path), Err(CornellError::Rectangles { .. })),
            "{bad:?}"
        );
    }
    assert!(matches!(
        read_rectangles(&dir.path().join("missing.txt")),
        Err(CornellError::Io { .. })
    ));
}
