//! Grasp data from the robot's world: the free gripper's labels are physics outcomes, the
//! robot's planner refuses a grasp whose finger lands on the object, and a set is the same bytes
//! whatever the number of threads. Physics: run in release.

use std::collections::BTreeMap;
use std::path::Path;

use lgdm_pointcloud::grasp::cornell::{GraspIndex, read_rectangles};
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_sim::datagen::grasp_data::{GraspDataJob, GraspDataSetup};
use lgdm_sim::grasping::attempt::{AttemptConfig, FailureReason, plan_grasp_for};
use lgdm_sim::grasping::free_grasp::{FreeGrasp, try_grasp};
use lgdm_sim::perception::{Perception, WorldGrasp};
use lgdm_sim::physics::config::WorldConfig;
use lgdm_sim::physics::world::World;
use lgdm_sim::robot::gripper::GripperConfig;
use lgdm_sim::run::objects::ObjectSource;

/// A box 4 cm across x, 16 cm along y (wider than the 2F-140's 14 cm stroke), 6 cm tall.
fn narrow_box() -> (World, lgdm_sim::physics::object::ObjectHandle, [f64; 3]) {
    let mut world = World::new(WorldConfig::default()).unwrap();
    let top = world.config().table.top_z_m();
    let mesh = Mesh::cuboid([0.0, 0.0, 0.03], [0.04, 0.16, 0.06], [60, 90, 200]);
    let at = [0.05, -0.55, top];
    let h = world.spawn_object("box", &mesh, &translation(at)).unwrap();
    world.settle();
    (world, h, at.map(f64::from))
}

#[test]
fn a_grasp_across_a_narrow_box_holds_and_one_along_it_does_not() {
    let gripper = GripperConfig::default();
    let config = AttemptConfig::default();
    let tip_from_tcp = f64::from(gripper.tip_from_tcp_m());
    for (yaw, opening, holds) in [
        (0.0, 0.08, true),
        (std::f64::consts::FRAC_PI_2, 0.14, false),
    ] {
        let (mut world, h, [x, y, top]) = narrow_box();
        let grasp = FreeGrasp {
            tcp_m: [x, y, top + 0.03 + tip_from_tcp],
            yaw_rad: yaw,
            opening_m: opening,
            pregrasp_z_m: top + 0.2 + tip_from_tcp,
        };
        let trial = try_grasp(&mut world, &gripper, &grasp, Some(h), &config).unwrap();
        assert_eq!(trial.success, holds, "yaw {yaw}: {trial:?}");
        if !holds {
            // The fingers land on the box's top: the descent stops far above the plan.
            assert_eq!(
                trial.reason,
                Some(FailureReason::CollisionOnApproach),
                "{trial:?}"
            );
        }
        assert!(trial.steps > 100, "{trial:?}");
        // The gripper is gone: only the box is left in the world, where the trial left it.
        assert_eq!(world.objects().count(), 1);
    }
}

#[test]
fn the_planner_refuses_a_grasp_whose_finger_lands_on_the_object() {
    let (world, _, [x, y, top]) = narrow_box();
    let perception = Perception::new(Default::default()).unwrap();
    let scene = perception.look(&world).unwrap();
    let view = perception.close_up(&world, &scene, 0).unwrap();
    let gripper = GripperConfig::default();
    let config = AttemptConfig::default();
    let plan = |yaw_rad: f64, opening_m: f64| {
        let grasp = WorldGrasp {
            position_m: [x, y, top + 0.06],
            yaw_rad,
            opening_m,
            quality: 1.0,
        };
        plan_grasp_for(&gripper, top, &view, &grasp, &config)
    };
    let across = plan(0.0, 0.05);
    assert!(across.reaches_contacts(&config), "{across:?}");
    // Along the box with an 8 cm opening, each finger's lane is on the box's top: the tips are
    // lifted clear of it and would close on air.
    let along = plan(std::f64::consts::FRAC_PI_2, 0.08);
    assert!(along.lane_height_m > 0.05, "{along:?}");
    assert!(!along.reaches_contacts(&config), "{along:?}");
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for entry in walk(dir) {
        let name = entry.strip_prefix(dir).unwrap().display().to_string();
        out.insert(name, std::fs::read(&entry).unwrap());
    }
    out
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else if !p.ends_with(lgdm_base::LOCK_FILE) {
            out.push(p);
        }
    }
    out
}

#[test]
fn a_set_is_the_same_bytes_for_any_number_of_threads_and_its_labels_are_outcomes() {
    let setup = GraspDataSetup {
        scenes: 4,
        seed: 3,
        objects: Some(ObjectSource::Procedural {
            instances: 1,
            seed: 3,
        }),
        analytic: 3,
        random: 3,
        ..GraspDataSetup::default()
    };
    let job = GraspDataJob::prepare(setup).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (one, two) = (tmp.path().join("one"), tmp.path().join("two"));
    let summary = job.run(&one, false, 1, |_| {}).unwrap();
    assert_eq!(job.run(&two, false, 2, |_| {}).unwrap(), summary);
    assert_eq!(files(&one), files(&two));
    assert!(one.join("grasp_preview.png").is_file());
    // A set is not written over without force.
    assert!(job.run(&one, false, 1, |_| {}).is_err());

    let index: GraspIndex =
        serde_json::from_slice(&std::fs::read(one.join("index.json")).unwrap()).unwrap();
    assert_eq!(index.images.len(), summary.images);
    assert!(summary.images >= 4, "{summary:?}");
    let (mut held, mut tried) = (0, 0);
    for image in &index.images {
        let physics = image.physics.as_ref().expect("physics labels");
        let pos = read_rectangles(&one.join(format!("{}cpos.txt", image.prefix))).unwrap();
        let neg = read_rectangles(&one.join(format!("{}cneg.txt", image.prefix))).unwrap();
        assert_eq!(pos.len(), physics.positives.len());
        assert_eq!(neg.len(), physics.negatives.len());
        assert!(
            physics
                .positives
                .iter()
                .all(|o| o.success && o.reason.is_none())
        );
        assert!(
            physics
                .negatives
                .iter()
                .all(|o| !o.success && o.reason.is_some())
        );
        held += pos.len();
        tried += pos.len() + neg.len();
    }
    assert_eq!((held, tried), (summary.all.held, summary.all.tried));
    // Both outcomes occur: the labels separate grasps.
    assert!(held > 0 && held < tried, "{summary:?}");
}

#[test]
fn rim_grasps_are_tried_on_open_objects_and_never_on_closed_ones() {
    // Two open objects and a closed one, as meshes in the gen-dataset layout, one per table.
    let tmp = tempfile::tempdir().unwrap();
    let meshes = tmp.path().join("meshes");
    for (category, name) in [("cup", "glass"), ("mug", "mug"), ("can", "can")] {
        let dir = meshes.join(category);
        std::fs::create_dir_all(&dir).unwrap();
        let mesh = lgdm_pointcloud::objects::procedural_object(name, 0, 1).unwrap();
        std::fs::write(dir.join(format!("{name}.obj")), mesh.to_obj()).unwrap();
    }
    let setup = GraspDataSetup {
        scenes: 6,
        seed: 1,
        objects: Some(ObjectSource::Meshes {
            dir: meshes,
            units: lgdm_pointcloud::import::MeshUnits::parse(&["m"]).unwrap(),
        }),
        isolated_share: 1.0,
        analytic: 1,
        random: 0,
        rim: 3,
        ..GraspDataSetup::default()
    };
    let job = GraspDataJob::prepare(setup).unwrap();
    let out = tmp.path().join("set");
    let summary = job.run(&out, false, 2, |_| {}).unwrap();
    let index: GraspIndex =
        serde_json::from_slice(&std::fs::read(out.join("index.json")).unwrap()).unwrap();
    let mut rim_on = BTreeMap::<String, usize>::new();
    for image in &index.images {
        let physics = image.physics.as_ref().unwrap();
        let rims = physics
            .positives
            .iter()
            .chain(&physics.negatives)
            .filter(|o| o.source == "rim")
            .count();
        *rim_on.entry(image.category_name.clone()).or_default() += rims;
    }
    assert!(rim_on.contains_key("can"), "a can was imaged: {rim_on:?}");
    assert_eq!(rim_on["can"], 0, "{rim_on:?}");
    assert!(rim_on.get("cup").copied().unwrap_or(0) + rim_on.get("mug").copied().unwrap_or(0) > 0);
    let tally = summary.by_source["rim"];
    assert_eq!(tally.tried, rim_on.values().sum::<usize>(), "{summary:?}");
}
