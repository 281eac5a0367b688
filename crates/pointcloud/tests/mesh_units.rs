//! A mesh file's unit is given (`MeshUnits`: every file, one file) or guessed from its size:
//! the unit in which its largest extent is a household object's, 2 cm to 60 cm. A size that
//! fits two units (a 43 mm golf ball is also a plausible 43 cm) or none is an error naming the
//! file and asking for the unit, before anything is written; the unit, how it was chosen and
//! the size in metres are reported and recorded in the manifest. The contact sheet draws all
//! objects at one scale with a size bar.

use std::path::Path;

use lgdm_pointcloud::dataset::{
    Dataset, DatasetError, DatasetSpec, generate, standard_collections,
};
use lgdm_pointcloud::import::{
    ImportReport, LengthUnit, MeshImportError, MeshUnits, UnitSource, load_mesh, load_mesh_in,
    load_mesh_library,
};
use lgdm_pointcloud::math::transform_point;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::objects::{ObjectModel, rest_on_table};
use lgdm_pointcloud::preview::{SIZE_BAR_COLOR, TILE_W, contact_sheet_tiles};

/// A closed ball of diameter `d` file units (a lathed semicircle).
fn ball(d: f32) -> Mesh {
    let r = d / 2.0;
    let profile: Vec<[f32; 2]> = (0..=16)
        .map(|i| {
            let a = std::f32::consts::PI * i as f32 / 16.0;
            [r * a.sin(), r - r * a.cos()]
        })
        .collect();
    Mesh::lathe(&profile, 24, [230, 230, 230])
}

/// An open cup `h` file units tall, `0.8 h` wide.
fn cup(h: f32) -> Mesh {
    let r = 0.4 * h;
    let profile = [
        [0.0, 0.0],
        [r, 0.0],
        [r, h],
        [0.9 * r, h],
        [0.9 * r, 0.1 * h],
        [0.0, 0.1 * h],
    ];
    Mesh::lathe(&profile, 24, [200, 60, 40])
}

/// A box of `size` file units.
fn cuboid(size: [f32; 3]) -> Mesh {
    Mesh::cuboid([0.0; 3], size, [90, 90, 200])
}

fn write(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// A small spec over the meshes in `dir`: two collections, two frames, one grasp image.
fn mesh_spec(dir: &Path, units: MeshUnits) -> DatasetSpec {
    let mut spec = DatasetSpec::small(4);
    spec.meshes = Some(dir.to_path_buf());
    spec.mesh_units = units;
    spec.collections = standard_collections().into_iter().take(2).collect();
    spec.frames_per_sequence = 2;
    spec.grasp_images = 1;
    spec.previews = false;
    spec
}

#[test]
fn sizes_that_fit_two_units_are_errors_asking_for_units() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    // A 43 mm golf ball and a 58 mm cup in millimetres; a 25 cm bottle in centimetres. Each is
    // household-sized in mm and in cm.
    let cases = [
        (
            "ball/golf_ball.obj",
            ball(43.0).to_obj(),
            "0.043 m",
            "0.43 m",
        ),
        ("cup/espresso.obj", cup(58.0).to_obj(), "0.058 m", "0.58 m"),
        (
            "bottle/bottle.obj",
            cuboid([7.0, 7.0, 25.0]).to_obj(),
            "0.025 m",
            "0.25 m",
        ),
    ];
    for (file, text, in_mm, in_cm) in &cases {
        let path = meshes.join(file);
        write(&path, text);
        let err = load_mesh(&path).map(|_| ()).unwrap_err();
        match &err {
            MeshImportError::AmbiguousUnit { candidates, .. } => assert_eq!(
                candidates,
                &[LengthUnit::Millimetre, LengthUnit::Centimetre],
                "{file}"
            ),
            other => panic!("{file}: expected an ambiguous unit, got {other}"),
        }
        let msg = err.to_string();
        let name = Path::new(file).file_name().unwrap().to_str().unwrap();
        for part in [name, *in_mm, *in_cm, "--units"] {
            assert!(msg.contains(part), "{file}: `{part}` missing from: {msg}");
        }
    }
    // Through the library and the generator: the error names the file as --units takes it,
    // and nothing is written.
    let err = load_mesh_library(&meshes, &MeshUnits::guess())
        .map(|_| ())
        .unwrap_err();
    assert!(
        err.to_string()
            .contains("--units ball/golf_ball.obj=mm|cm|m"),
        "{err}"
    );
    let out = dir.path().join("data");
    let err = generate(&mesh_spec(&meshes, MeshUnits::guess()), &out, &mut |_| {}).unwrap_err();
    assert!(
        matches!(
            err,
            DatasetError::Mesh(MeshImportError::AmbiguousUnit { .. })
        ),
        "{err}"
    );
    assert!(!out.exists(), "output written despite the error");
}

#[test]
fn given_units_give_objects_of_the_right_size() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    write(&meshes.join("ball/golf_ball.obj"), &ball(43.0).to_obj());
    write(&meshes.join("cup/espresso.obj"), &cup(62.0).to_obj());
    let units = MeshUnits::parse(&["mm"]).unwrap();
    let lib = load_mesh_library(&meshes, &units).unwrap();
    let sizes: Vec<(&str, f32)> = lib
        .iter()
        .map(|o| {
            let (lo, hi) = o.object.mesh.bounds().unwrap();
            let e = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f32::max);
            (o.report.file.as_str(), e)
        })
        .collect();
    assert_eq!(sizes[0].0, "ball/golf_ball.obj");
    assert!((sizes[0].1 - 0.043).abs() < 1e-5, "{sizes:?}");
    assert_eq!(sizes[1].0, "cup/espresso.obj");
    assert!((sizes[1].1 - 0.062).abs() < 1e-5, "{sizes:?}");
    assert_eq!(
        lib[0].report,
        ImportReport {
            file: "ball/golf_ball.obj".into(),
            unit: LengthUnit::Millimetre,
            unit_source: UnitSource::Given,
            largest_extent_m: lib[0].report.largest_extent_m,
            sidecar: Default::default(),
        }
    );
    assert!((lib[0].report.largest_extent_m - 0.043).abs() < 1e-5);
    assert_eq!(
        lib[0].report.describe(),
        "units mm (given), largest extent 0.043 m"
    );
    let m = load_mesh_in(&meshes.join("ball/golf_ball.obj"), LengthUnit::Millimetre).unwrap();
    assert_eq!(m, lib[0].object.mesh);

    // The dataset: rendered views of the golf ball are 43 mm across, not 43 cm, and the
    // manifest records the unit (spec and instances).
    let out = dir.path().join("data");
    let manifest = generate(&mesh_spec(&meshes, units.clone()), &out, &mut |_| {}).unwrap();
    assert_eq!(manifest.spec.mesh_units, units);
    let imports: Vec<&ImportReport> = manifest
        .instances
        .iter()
        .map(|i| i.import.as_ref().unwrap())
        .collect();
    assert_eq!(imports[0], &lib[0].report);
    assert_eq!(imports[1], &lib[1].report);
    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.manifest(), &manifest);
    // Heights above the table (world z, which the turntable does not change): both objects
    // are as tall as their largest extent; the lowest part of the ball is hidden from a camera
    // looking down at 35°, and the ball is only ~16 px across.
    let world_from_camera = manifest.camera.world_from_camera;
    for seq in ds.sequences(0).unwrap() {
        let seq = seq.unwrap();
        let height = [0.043, 0.062][seq.instance as usize];
        for cloud in &seq.frames {
            let z: Vec<f32> = cloud
                .points
                .iter()
                .map(|&p| transform_point(&world_from_camera, p)[2])
                .collect();
            let seen = z.iter().fold(f32::MIN, |a, &b| a.max(b))
                - z.iter().fold(f32::MAX, |a, &b| a.min(b));
            assert!(
                seen > 0.7 * height && seen < 1.02 * height,
                "instance {}: views {seen} m high, the object is {height} m",
                seq.instance
            );
        }
    }
}

#[test]
fn unambiguous_sizes_are_guessed_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    // (file, mesh, guessed unit, size in metres). 62 mm: 62 cm is over 60 cm; 300 mm: 300 cm
    // is 3 m; 12 cm: 12 mm is under 2 cm; 0.25 m: 0.25 cm is under 2 cm; 600 mm (the limit).
    let cases = [
        ("a/cup_mm.obj", cup(62.0), LengthUnit::Millimetre, 0.062),
        (
            "a/box_mm.obj",
            cuboid([300.0, 100.0, 80.0]),
            LengthUnit::Millimetre,
            0.3,
        ),
        (
            "b/box_limit_mm.obj",
            cuboid([600.0, 100.0, 80.0]),
            LengthUnit::Millimetre,
            0.6,
        ),
        (
            "b/box_cm.obj",
            cuboid([12.0, 8.0, 5.0]),
            LengthUnit::Centimetre,
            0.12,
        ),
        (
            "c/box_m.obj",
            cuboid([0.25, 0.1, 0.1]),
            LengthUnit::Metre,
            0.25,
        ),
    ];
    for (file, mesh, _, _) in &cases {
        write(&meshes.join(file), &mesh.to_obj());
    }
    let lib = load_mesh_library(&meshes, &MeshUnits::guess()).unwrap();
    let mut files: Vec<&str> = cases.iter().map(|c| c.0).collect();
    files.sort();
    assert_eq!(
        lib.iter()
            .map(|o| o.report.file.as_str())
            .collect::<Vec<_>>(),
        files
    );
    for (file, _, unit, size_m) in &cases {
        let o = lib.iter().find(|o| o.report.file == *file).unwrap();
        assert_eq!(o.report.unit, *unit, "{file}");
        assert_eq!(o.report.unit_source, UnitSource::Guessed, "{file}");
        assert!(
            (o.report.largest_extent_m - size_m).abs() < 1e-4 * size_m.max(1.0),
            "{file}: {} m",
            o.report.largest_extent_m
        );
        assert!(o.report.is_plausible());
        assert_eq!(load_mesh(&meshes.join(file)).unwrap().1, *unit, "{file}");
    }
    let cup = lib
        .iter()
        .find(|o| o.report.file == "a/cup_mm.obj")
        .unwrap();
    assert_eq!(
        cup.report.describe(),
        "units mm (guessed), largest extent 0.062 m"
    );
    // The rule itself, at and around its limits.
    assert_eq!(
        LengthUnit::plausible_units(43.0),
        [LengthUnit::Millimetre, LengthUnit::Centimetre]
    );
    assert_eq!(
        LengthUnit::plausible_units(20.0),
        [LengthUnit::Millimetre, LengthUnit::Centimetre]
    );
    assert_eq!(
        LengthUnit::plausible_units(60.0),
        [LengthUnit::Millimetre, LengthUnit::Centimetre]
    );
    assert_eq!(LengthUnit::plausible_units(19.0), [LengthUnit::Centimetre]);
    assert_eq!(LengthUnit::plausible_units(61.0), [LengthUnit::Millimetre]);
    assert_eq!(LengthUnit::plausible_units(0.6), [LengthUnit::Metre]);
    assert_eq!(LengthUnit::plausible_units(2.0), [LengthUnit::Centimetre]);
    assert!(LengthUnit::plausible_units(1.0).is_empty());
}

#[test]
fn sizes_that_fit_no_unit_are_errors_unless_the_unit_is_given() {
    let dir = tempfile::tempdir().unwrap();
    // 1500 units: 1.5 m, 15 m or 1500 m. 0.7 units: 0.7 m is over 60 cm, 0.7 cm under 2 cm.
    // 0.005 units: 5 mm at most.
    for (name, mesh, in_m) in [
        ("table.obj", cuboid([1500.0, 800.0, 750.0]), "1500 m"),
        ("chair.obj", cuboid([0.5, 0.5, 0.7]), "0.7 m"),
        ("bead.obj", ball(0.005), "0.005 m"),
    ] {
        let path = dir.path().join(name);
        write(&path, &mesh.to_obj());
        let err = load_mesh(&path).map(|_| ()).unwrap_err();
        assert!(
            matches!(err, MeshImportError::NoPlausibleUnit { .. }),
            "{name}: {err}"
        );
        let msg = err.to_string();
        for part in [name, in_m, "in no unit", "--units"] {
            assert!(msg.contains(part), "{name}: `{part}` missing from: {msg}");
        }
    }
    // Given, the unit is used as it is, and the report says the size is not household-sized.
    let meshes = dir.path().join("meshes");
    write(
        &meshes.join("furniture/chair.obj"),
        &cuboid([0.5, 0.5, 0.7]).to_obj(),
    );
    let lib = load_mesh_library(&meshes, &MeshUnits::parse(&["m"]).unwrap()).unwrap();
    assert!((lib[0].report.largest_extent_m - 0.7).abs() < 1e-5);
    assert!(!lib[0].report.is_plausible());
}

#[test]
fn per_file_units_take_precedence_over_every_file_units() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    write(&meshes.join("ball/golf_ball.obj"), &ball(43.0).to_obj());
    write(
        &meshes.join("box/crate.obj"),
        &cuboid([0.3, 0.2, 0.2]).to_obj(),
    );
    let report = |units: &[&str], file: &str| -> ImportReport {
        let units = MeshUnits::parse(units).unwrap();
        load_mesh_library(&meshes, &units)
            .unwrap()
            .into_iter()
            .find(|o| o.report.file == file)
            .unwrap()
            .report
    };
    // Only the ambiguous file given: the other is still guessed.
    let ball = report(&["ball/golf_ball.obj=mm"], "ball/golf_ball.obj");
    assert_eq!(
        (ball.unit, ball.unit_source),
        (LengthUnit::Millimetre, UnitSource::GivenForFile)
    );
    assert!((ball.largest_extent_m - 0.043).abs() < 1e-5);
    let crate_ = report(&["ball/golf_ball.obj=mm"], "box/crate.obj");
    assert_eq!(
        (crate_.unit, crate_.unit_source),
        (LengthUnit::Metre, UnitSource::Guessed)
    );
    // A per-file unit wins over the every-file unit.
    let ball = report(&["cm", "ball/golf_ball.obj=mm"], "ball/golf_ball.obj");
    assert_eq!(ball.unit, LengthUnit::Millimetre);
    let crate_ = report(&["cm", "ball/golf_ball.obj=mm"], "box/crate.obj");
    assert_eq!(
        (crate_.unit, crate_.unit_source),
        (LengthUnit::Centimetre, UnitSource::Given)
    );
    // A unit for a file that is not there is an error naming it.
    let units = MeshUnits::parse(&["ball/golf.obj=mm"]).unwrap();
    let err = load_mesh_library(&meshes, &units).map(|_| ()).unwrap_err();
    assert!(
        matches!(err, MeshImportError::UnknownUnitFile { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("`ball/golf.obj`"), "{err}");
    // Malformed entries.
    for (entries, message) in [
        (&["inch"][..], "unknown unit `inch`"),
        (&["mm", "cm"][..], "given twice"),
        (&["a/b.obj=mm", "a/b.obj=cm"][..], "given twice"),
        (&["a/b.obj=feet"][..], "unknown unit `feet`"),
        (&["b.obj=mm"][..], "<category>/<file>"),
        (&["../b.obj=mm"][..], "<category>/<file>"),
        (&["a/../../b.obj=mm"][..], "<category>/<file>"),
    ] {
        let err = MeshUnits::parse(entries).unwrap_err();
        assert!(err.contains(message), "{entries:?}: {err}");
    }
}

#[test]
fn mesh_units_are_in_the_spec_only_with_meshes() {
    // Units without meshes are refused, naming the field.
    let mut spec = DatasetSpec::small(0);
    spec.mesh_units = MeshUnits::parse(&["mm"]).unwrap();
    match spec.validate() {
        Err(DatasetError::InvalidSpec { field, .. }) => assert_eq!(field, "mesh_units"),
        other => panic!("expected an invalid mesh_units, got {other:?}"),
    }
    // They round-trip through the spec's JSON; a spec without them has no such key (so
    // procedural datasets' manifests keep their bytes).
    spec.meshes = Some("meshes".into());
    spec.mesh_units = MeshUnits::parse(&["cm", "ball/golf_ball.obj=mm"]).unwrap();
    spec.validate().unwrap();
    let json = serde_json::to_value(&spec).unwrap();
    assert_eq!(
        json["mesh_units"],
        serde_json::json!({"all": "cm", "files": {"ball/golf_ball.obj": "mm"}})
    );
    let back: DatasetSpec = serde_json::from_value(json).unwrap();
    assert_eq!(back, spec);
    let plain = serde_json::to_value(DatasetSpec::small(0)).unwrap();
    assert!(plain.get("mesh_units").is_none());
}

/// A cube of side `side_m` metres resting on the table, in a colour no overlay uses.
fn red_cube(name: &str, side_m: f32) -> ObjectModel {
    let mut mesh = Mesh::cuboid([0.0; 3], [side_m; 3], [220, 20, 20]);
    rest_on_table(&mut mesh);
    ObjectModel {
        name: name.into(),
        category: "cube".into(),
        mesh,
        physics: Default::default(),
        parts: Vec::new(),
    }
}

/// Width in pixels of the red object's silhouette in a tile.
fn silhouette_width(tile: &lgdm_pointcloud::image::RgbImage) -> usize {
    let (mut lo, mut hi) = (usize::MAX, 0);
    for y in 0..tile.height {
        for x in 0..tile.width {
            let [r, g, b] = tile.get(x, y);
            if r > 60 && g < r / 3 && b < r / 3 {
                (lo, hi) = (lo.min(x), hi.max(x));
            }
        }
    }
    assert!(hi >= lo, "no object pixel in the tile");
    hi - lo + 1
}

#[test]
fn contact_sheet_draws_objects_at_one_scale_with_a_size_bar() {
    // A 10 cm and a 50 cm cube: at one scale the large one is five times as wide.
    let objects = [red_cube("small", 0.1), red_cube("large", 0.5)];
    let (scale, tiles) = contact_sheet_tiles(&objects);
    assert_eq!(tiles.len(), 2);
    let (small, large) = (silhouette_width(&tiles[0]), silhouette_width(&tiles[1]));
    let ratio = large as f32 / small as f32;
    assert!(
        (4.0..=6.5).contains(&ratio),
        "silhouettes {small} px and {large} px: ratio {ratio}, expected about 5"
    );
    // The scale is real: a cube seen from 19° off its face is 1.0 to 1.45 sides wide.
    let small_m = small as f32 * scale.metres_per_px;
    assert!(
        (0.1..=0.145).contains(&small_m),
        "10 cm cube drawn {small_m} m wide at {} m/px",
        scale.metres_per_px
    );
    // The size bar: a round length, as many pixels as that length at the common scale, the
    // longest round length within a third of the tile, drawn in every tile.
    let nice = [0.01f32, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0];
    let k = nice
        .iter()
        .position(|&m| (m - scale.bar_m).abs() < 1e-6)
        .expect("bar length is 1, 2 or 5 × 10ⁿ");
    assert_eq!(
        scale.bar_px,
        (scale.bar_m / scale.metres_per_px).round() as usize
    );
    assert!(scale.bar_px <= TILE_W / 3 && nice[k + 1] / scale.metres_per_px > (TILE_W / 3) as f32);
    for tile in &tiles {
        let longest_run = (0..tile.height)
            .map(|y| {
                let (mut best, mut run) = (0, 0);
                for x in 0..tile.width {
                    run = if tile.get(x, y) == SIZE_BAR_COLOR {
                        run + 1
                    } else {
                        0
                    };
                    best = best.max(run);
                }
                best
            })
            .max()
            .unwrap();
        assert_eq!(longest_run, scale.bar_px);
    }
    // A 10× unit mistake: the same 10 cm cube among 1 m objects shrinks accordingly, while the
    // 10 cm cube alone fills its tile.
    let alone = contact_sheet_tiles(&objects[..1]);
    let with_big = contact_sheet_tiles(&[red_cube("small", 0.1), red_cube("mistake", 1.0)]);
    let (w_alone, w_with_big) = (
        silhouette_width(&alone.1[0]),
        silhouette_width(&with_big.1[0]),
    );
    assert!(
        w_alone > 7 * w_with_big,
        "{w_alone} px alone vs {w_with_big} px next to a 1 m cube"
    );
}
