//! `objects.toml` beside a mesh library (issue 23): every field takes effect on the imported
//! object (unit, rest pose, colour, mass and friction for the simulator), a `--units` flag wins
//! over the sidecar's unit, and every bad value is refused naming the sidecar and the field.

use std::path::Path;

use lgdm_pointcloud::import::{
    LengthUnit, MeshImportError, MeshUnits, UnitSource, load_mesh_library,
};
use lgdm_pointcloud::mesh::Mesh;
use lgdm_pointcloud::sidecar::SIDECAR_FILE;

/// A library of two boxes in millimetres: `box/tall.obj` (20 × 40 × 100 mm, standing) and
/// `box/flat.obj` (60 × 60 × 30 mm), with `sidecar` as its objects.toml (none when empty).
fn library(dir: &Path, sidecar: &str) {
    std::fs::create_dir_all(dir.join("box")).unwrap();
    let tall = Mesh::cuboid([0.0; 3], [20.0, 40.0, 100.0], [200, 200, 200]);
    let flat = Mesh::cuboid([0.0; 3], [60.0, 60.0, 30.0], [200, 200, 200]);
    std::fs::write(dir.join("box/tall.obj"), tall.to_obj()).unwrap();
    std::fs::write(dir.join("box/flat.obj"), flat.to_obj()).unwrap();
    if !sidecar.is_empty() {
        std::fs::write(dir.join(SIDECAR_FILE), sidecar).unwrap();
    }
}

fn extents(mesh: &Mesh) -> [f32; 3] {
    let (lo, hi) = mesh.bounds().unwrap();
    [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]
}

fn close(a: [f32; 3], b: [f32; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-4)
}

#[test]
fn every_field_takes_effect() {
    let dir = tempfile::tempdir().unwrap();
    library(
        dir.path(),
        r##"
[all]
unit = "mm"
friction = 0.4

[files."box/tall.obj"]
rest_rpy_deg = [90.0, 0.0, 0.0]
colour = "#e0b81c"
mass_kg = 0.25
friction = 0.9
"##,
    );
    let lib = load_mesh_library(dir.path(), &MeshUnits::guess()).unwrap();
    let [flat, tall] = [&lib[0], &lib[1]];
    assert_eq!(tall.object.name, "tall");
    // Millimetres from [all]; lying on its side: the 100 mm height along −y, 40 mm tall.
    assert_eq!(tall.report.unit, LengthUnit::Millimetre);
    assert_eq!(tall.report.unit_source, UnitSource::Sidecar);
    assert!(
        close(extents(&tall.object.mesh), [0.02, 0.1, 0.04]),
        "{:?}",
        extents(&tall.object.mesh)
    );
    let (lo, _) = tall.object.mesh.bounds().unwrap();
    assert!(lo[2].abs() < 1e-6, "rests on z = 0");
    assert!(
        tall.object
            .mesh
            .colors
            .iter()
            .all(|&c| c == [0xe0, 0xb8, 0x1c])
    );
    assert_eq!(tall.object.physics.mass_kg, Some(0.25));
    assert_eq!(
        tall.object.physics.friction,
        Some(0.9),
        "the file's own value wins"
    );
    assert_eq!(
        tall.report.sidecar.colour.as_deref(),
        Some("#e0b81c"),
        "recorded"
    );
    // The other file: [all] only.
    assert!(close(extents(&flat.object.mesh), [0.06, 0.06, 0.03]));
    assert_eq!(flat.object.physics.mass_kg, None);
    assert_eq!(flat.object.physics.friction, Some(0.4));
    assert!(
        flat.object
            .mesh
            .colors
            .iter()
            .all(|&c| c != [0xe0, 0xb8, 0x1c])
    );
}

#[test]
fn a_units_flag_wins_over_the_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    library(dir.path(), "[all]\nunit = \"m\"\n");
    // The sidecar says metres (a 100 m box); the flag says millimetres and is what counts.
    let units = MeshUnits::parse(&["mm"]).unwrap();
    let lib = load_mesh_library(dir.path(), &units).unwrap();
    assert_eq!(lib[1].report.unit, LengthUnit::Millimetre);
    assert_eq!(lib[1].report.unit_source, UnitSource::Given);
}

#[test]
fn no_sidecar_changes_nothing() {
    let plain = tempfile::tempdir().unwrap();
    library(plain.path(), "");
    let lib = load_mesh_library(plain.path(), &MeshUnits::parse(&["mm"]).unwrap()).unwrap();
    assert!(lib.iter().all(|o| o.report.sidecar.is_empty()));
    assert!(lib.iter().all(|o| o.object.physics == Default::default()));
    assert!(
        close(extents(&lib[1].object.mesh), [0.02, 0.04, 0.1]),
        "standing as the file lies"
    );
}

#[test]
fn bad_values_are_refused_naming_the_sidecar_and_the_field() {
    let cases = [
        ("[all]\nunit = \"inch\"\n", "unit"),
        ("[all]\nmass_kg = -1.0\n", "all.mass_kg"),
        ("[all]\nmass_kg = 100.0\n", "all.mass_kg"),
        ("[all]\nfriction = -0.1\n", "all.friction"),
        ("[all]\nfriction = 11.0\n", "all.friction"),
        (
            "[files.\"box/tall.obj\"]\nrest_rpy_deg = [0.0, 400.0, 0.0]\n",
            "files.\"box/tall.obj\".rest_rpy_deg",
        ),
        (
            "[files.\"box/tall.obj\"]\ncolour = \"red\"\n",
            "files.\"box/tall.obj\".colour",
        ),
        ("[files.\"box/tall.obj\"]\ncolor = \"#ff0000\"\n", "color"),
        (
            "[files.\"box/short.obj\"]\nmass_kg = 0.1\n",
            "files.\"box/short.obj\": no such mesh",
        ),
        (
            "[files.\"tall.obj\"]\nmass_kg = 0.1\n",
            "files.\"tall.obj\": name the file",
        ),
        ("[everything]\nunit = \"m\"\n", "everything"),
        ("[all\n", "objects.toml"),
    ];
    for (text, want) in cases {
        let dir = tempfile::tempdir().unwrap();
        library(dir.path(), text);
        let err = load_mesh_library(dir.path(), &MeshUnits::guess()).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, MeshImportError::Sidecar(_)), "{text}: {msg}");
        assert!(msg.contains(SIDECAR_FILE), "{text}: names the file: {msg}");
        assert!(msg.contains(want), "{text}: names {want}: {msg}");
    }
}
