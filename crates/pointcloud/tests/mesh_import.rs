//! User meshes import from `<dir>/<category>/<instance>.{obj,stl,ply}` in metres (millimetre
//! and centimetre files of unambiguous size detected; see mesh_units.rs), centred and resting
//! on the table; broken or empty meshes give errors naming the file, never panics. Meshes read
//! from a separate (temporary) folder give the same bytes wherever that folder is.

use std::path::Path;

use lgdm_pointcloud::dataset::{
    Dataset, DatasetSpec, generate, generate_from_meshes, standard_collections,
};
use lgdm_pointcloud::import::{LengthUnit, MeshUnits, load_mesh, load_mesh_library};
use lgdm_pointcloud::mesh::Mesh;

/// An OBJ box of `size` (file units) with its minimum corner at `offset`.
fn obj_box(size: [f32; 3], offset: [f32; 3]) -> String {
    let m = Mesh::cuboid([0.0; 3], size, [0; 3]);
    let mut s = String::from("# test box\no box\n");
    for v in &m.vertices {
        s += &format!(
            "v {} {} {}\n",
            v[0] + offset[0] + size[0] / 2.0,
            v[1] + offset[1] + size[1] / 2.0,
            v[2] + offset[2] + size[2] / 2.0
        );
    }
    for t in &m.triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

fn write(path: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn units_are_detected_and_meshes_rest_on_the_table() {
    let dir = tempfile::tempdir().unwrap();
    // 80 × 60 × 120 mm box far from the origin.
    let p = dir.path().join("mm.obj");
    write(&p, obj_box([80.0, 60.0, 120.0], [500.0, -300.0, 40.0]));
    let (m, unit) = load_mesh(&p).unwrap();
    assert_eq!(unit, LengthUnit::Millimetre);
    let (lo, hi) = m.bounds().unwrap();
    assert!((hi[2] - 0.12).abs() < 1e-5 && lo[2].abs() < 1e-6);
    assert!((lo[0] + 0.04).abs() < 1e-5 && (hi[1] - 0.03).abs() < 1e-5);
    // Same box in centimetres and metres.
    let p = dir.path().join("cm.obj");
    write(&p, obj_box([8.0, 6.0, 12.0], [0.0; 3]));
    assert_eq!(load_mesh(&p).unwrap().1, LengthUnit::Centimetre);
    let p = dir.path().join("m.obj");
    write(&p, obj_box([0.08, 0.06, 0.12], [0.0; 3]));
    let (m, unit) = load_mesh(&p).unwrap();
    assert_eq!(unit, LengthUnit::Metre);
    assert!((m.bounds().unwrap().1[2] - 0.12).abs() < 1e-6);
}

#[test]
fn stl_and_ply_load() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mesh::cuboid([0.0, 0.0, 0.05], [0.1, 0.1, 0.1], [0; 3]);
    let tris: Vec<stl_io::Triangle> = (0..m.len())
        .map(|i| {
            let [a, b, c] = m.triangle_vertices(i);
            stl_io::Triangle {
                normal: stl_io::Normal::new(m.face_normal(i)),
                vertices: [
                    stl_io::Vertex::new(a),
                    stl_io::Vertex::new(b),
                    stl_io::Vertex::new(c),
                ],
            }
        })
        .collect();
    let p = dir.path().join("a.stl");
    let mut f = std::fs::File::create(&p).unwrap();
    stl_io::write_stl(&mut f, tris.iter()).unwrap();
    drop(f);
    let (s, _) = load_mesh(&p).unwrap();
    assert_eq!(s.len(), 12);
    assert!((s.area() - 0.06).abs() < 1e-5);
    // ASCII PLY with a quad face and vertex colours.
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
               property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n\
               property list uchar int vertex_indices\nend_header\n\
               0 0 0 255 0 0\n0.1 0 0 255 0 0\n0.1 0.1 0 255 0 0\n0 0.1 0 255 0 0\n4 0 1 2 3\n";
    let p = dir.path().join("q.ply");
    write(&p, ply);
    let (q, _) = load_mesh(&p).unwrap();
    assert_eq!(q.len(), 2);
    assert_eq!(q.colors[0], [255, 0, 0]);
}

#[test]
fn broken_meshes_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty.obj", Vec::new()),
        ("no_faces.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n".to_vec()),
        ("bad_index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n".to_vec()),
        ("nan.obj", b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("flat_point.obj", b"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n".to_vec()),
        ("garbage.stl", b"solid x\n this is not an stl\n".to_vec()),
        ("truncated.stl", {
            let mut b = vec![0u8; 80];
            b.extend_from_slice(&10u32.to_le_bytes());
            b.extend_from_slice(&[0u8; 30]);
            b
        }),
        ("empty.ply", Vec::new()),
        ("bad_index.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n".to_vec()),
        ("no_faces.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n".to_vec()),
        ("mesh.dae", b"<xml/>".to_vec()),
    ];
    for (name, bytes) in cases {
        let p = dir.path().join(name);
        write(&p, &bytes);
        let err = load_mesh(&p).map(|_| ()).expect_err(name);
        assert!(err.to_string().contains(name), "{name}: {err}");
    }
    let err = load_mesh(&dir.path().join("missing.obj")).unwrap_err();
    assert!(err.to_string().contains("missing.obj"));
}

#[test]
fn library_layout_errors_and_generation_from_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = dir.path().join("meshes");
    // Empty root: error naming the directory.
    std::fs::create_dir_all(&meshes).unwrap();
    assert!(
        load_mesh_library(&meshes, &MeshUnits::guess())
            .unwrap_err()
            .to_string()
            .contains("meshes")
    );
    write(
        &meshes.join("boxes/tall.obj"),
        obj_box([0.06, 0.06, 0.2], [0.0; 3]),
    );
    write(
        &meshes.join("boxes/flat.obj"),
        obj_box([0.15, 0.1, 0.04], [0.0; 3]),
    );
    write(
        &meshes.join("bricks/brick.obj"),
        obj_box([200.0, 100.0, 60.0], [0.0; 3]),
    );
    write(&meshes.join("bricks/readme.txt"), "not a mesh");
    let lib = load_mesh_library(&meshes, &MeshUnits::guess()).unwrap();
    let names: Vec<_> = lib
        .iter()
        .map(|o| (o.object.category.as_str(), o.object.name.as_str()))
        .collect();
    assert_eq!(
        names,
        [("boxes", "flat"), ("boxes", "tall"), ("bricks", "brick")]
    );
    // A dataset from them.
    let mut spec = DatasetSpec::small(1);
    spec.meshes = Some(meshes.clone());
    spec.collections = standard_collections().into_iter().take(2).collect();
    spec.frames_per_sequence = 2;
    spec.grasp_images = 1;
    spec.previews = false;
    let out = dir.path().join("data");
    let manifest = generate(&spec, &out, &mut |_| {}).unwrap();
    assert_eq!(manifest.categories, ["boxes", "bricks"]);
    assert_eq!(manifest.instances[2].source, "bricks/brick");
    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.sequences(1).unwrap().count(), 3);
    // Duplicate instance names across categories; a broken file stops generation naming it.
    write(
        &meshes.join("bricks/tall.obj"),
        obj_box([0.1, 0.1, 0.1], [0.0; 3]),
    );
    assert!(
        load_mesh_library(&meshes, &MeshUnits::guess())
            .unwrap_err()
            .to_string()
            .contains("tall")
    );
    std::fs::remove_file(meshes.join("bricks/tall.obj")).unwrap();
    write(&meshes.join("bricks/zz_broken.stl"), b"nope");
    let err = generate(&spec, &dir.path().join("data2"), &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("zz_broken.stl"), "{err}");
}

#[test]
fn meshes_read_from_elsewhere_give_the_same_bytes_wherever_they_are() {
    let dir = tempfile::tempdir().unwrap();
    for copy in ["a", "b"] {
        write(
            &dir.path().join(copy).join("boxes/tall.obj"),
            obj_box([0.06, 0.06, 0.2], [0.0; 3]),
        );
    }
    let mut spec = DatasetSpec::small(3);
    spec.collections = standard_collections().into_iter().take(2).collect();
    spec.frames_per_sequence = 2;
    spec.grasp_images = 0;
    spec.previews = false;
    // `meshes` unset: refused, nothing written.
    let out_a = dir.path().join("data_a");
    let err = generate_from_meshes(&spec, &dir.path().join("a"), &out_a, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("meshes"), "{err}");
    assert!(!out_a.exists());
    spec.meshes = Some("where/they/came/from".into());
    let out_b = dir.path().join("data_b");
    let a = generate_from_meshes(&spec, &dir.path().join("a"), &out_a, &mut |_| {}).unwrap();
    let b = generate_from_meshes(&spec, &dir.path().join("b"), &out_b, &mut |_| {}).unwrap();
    assert_eq!(
        a.spec.meshes.as_deref(),
        Some(Path::new("where/they/came/from"))
    );
    assert_eq!(a.instances[0].source, "boxes/tall");
    for file in ["manifest.json", &a.collections[1].file] {
        assert_eq!(
            std::fs::read(out_a.join(file)).unwrap(),
            std::fs::read(out_b.join(file)).unwrap(),
            "{file}"
        );
    }
    assert_eq!(a, b);
}
