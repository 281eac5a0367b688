//! MCAP collections round-trip bit-exactly, a message decodes with the `foxglove.PointCloud`
//! schema's own (embedded) protobuf definition, and truncated or corrupt files give errors,
//! not panics.

use std::path::{Path, PathBuf};

use lgdm_pointcloud::dataset::{
    Dataset, DatasetError, DatasetSpec, Split, generate, standard_collections,
};
use prost::Message as _;

fn tiny_spec(seed: u64) -> DatasetSpec {
    let mut spec = DatasetSpec::small(seed);
    spec.preset = "tiny".into();
    spec.categories = vec!["mug".into(), "can".into()];
    spec.instances_per_category = 2;
    spec.collections = standard_collections()
        .into_iter()
        .filter(|c| ["clean", "noise_4mm", "dropout"].contains(&c.name.as_str()))
        .collect();
    spec.frames_per_sequence = 3;
    spec.grasp_images = 0;
    spec.previews = false;
    spec
}

fn generate_tiny(dir: &Path) -> lgdm_pointcloud::dataset::Manifest {
    generate(&tiny_spec(5), dir, &mut |_| {}).unwrap()
}

#[test]
fn written_clouds_read_back_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = generate_tiny(dir.path());
    assert_eq!(manifest.instances.len(), 4);
    assert_eq!(manifest.collections.len(), 3);
    assert_eq!(manifest.collections[2].split, Split::Test); // clean, dropout, noise_4mm
    let ds = Dataset::open(dir.path()).unwrap();
    // Regenerate the expected views directly and compare with what the reader returns.
    let spec = tiny_spec(5);
    let (objects, _, _) = lgdm_pointcloud::dataset::load_objects(&spec).unwrap();
    let camera = spec.camera.camera();
    for c in 0..3u32 {
        let seqs: Vec<_> = ds.sequences(c).unwrap().collect::<Result<_, _>>().unwrap();
        assert_eq!(seqs.len(), 4);
        for (o, seq) in seqs.iter().enumerate() {
            assert_eq!(seq.instance as usize, o);
            assert_eq!(seq.collection, c);
            assert_eq!(seq.category, manifest.instances[o].category);
            let expected =
                lgdm_pointcloud::dataset::render_views(&spec, c as usize, o, &objects[o], &camera);
            assert_eq!(seq.frames.len(), expected.len());
            for (a, b) in seq.frames.iter().zip(&expected) {
                let bits = |p: &[[f32; 3]]| {
                    p.iter()
                        .flat_map(|q| q.map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&a.points), bits(&b.points));
                assert_eq!(a.colors, b.colors);
            }
        }
    }
}

/// Reads the first message and the schema bytes of an MCAP file with the plain mcap reader.
fn first_message_and_schema(path: &Path) -> (Vec<u8>, String, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let mut stream = mcap::MessageStream::new(&bytes).unwrap();
    let msg = stream.next().unwrap().unwrap();
    let schema = msg.channel.schema.clone().unwrap();
    (msg.data.to_vec(), schema.name.clone(), schema.data.to_vec())
}

/// A generic protobuf decoder driven only by a `FileDescriptorSet`: returns field name → raw
/// values of the message `full_name`, recursing into nested messages.
#[derive(Debug)]
enum Value {
    Varint(u64),
    Fixed32(u32),
    Fixed64(u64),
    Bytes(Vec<u8>),
    Message(Vec<(String, Value)>),
}

fn varint(buf: &[u8], pos: &mut usize) -> u64 {
    let mut v = 0u64;
    let mut shift = 0;
    loop {
        let b = buf[*pos];
        *pos += 1;
        v |= u64::from(b & 0x7f) << shift;
        if b & 0x80 == 0 {
            return v;
        }
        shift += 7;
    }
}

fn decode_with_descriptor(
    fds: &prost_types::FileDescriptorSet,
    full_name: &str,
    buf: &[u8],
) -> Vec<(String, Value)> {
    use prost_types::field_descriptor_proto::Type;
    let (package, name) = full_name.rsplit_once('.').unwrap();
    let desc = fds
        .file
        .iter()
        .filter(|f| f.package() == package)
        .flat_map(|f| f.message_type.iter())
        .find(|m| m.name() == name)
        .unwrap_or_else(|| panic!("{full_name} not in the schema's descriptor set"));
    let mut out = Vec::new();
    let mut pos = 0;
    while pos < buf.len() {
        let key = varint(buf, &mut pos);
        let (number, wire) = ((key >> 3) as i32, key & 7);
        let field = desc
            .field
            .iter()
            .find(|f| f.number() == number)
            .unwrap_or_else(|| panic!("field {number} not in {full_name}"));
        let value = match wire {
            0 => Value::Varint(varint(buf, &mut pos)),
            1 => {
                let v = u64::from_le_bytes(buf[pos..pos + 8].try_into().unwrap());
                pos += 8;
                Value::Fixed64(v)
            }
            5 => {
                let v = u32::from_le_bytes(buf[pos..pos + 4].try_into().unwrap());
                pos += 4;
                Value::Fixed32(v)
            }
            2 => {
                let len = varint(buf, &mut pos) as usize;
                let body = buf[pos..pos + len].to_vec();
                pos += len;
                if field.r#type() == Type::Message {
                    Value::Message(decode_with_descriptor(
                        fds,
                        field.type_name().trim_start_matches('.'),
                        &body,
                    ))
                } else {
                    Value::Bytes(body)
                }
            }
            w => panic!("unexpected wire type {w}"),
        };
        // The wire type must agree with the declared field type.
        let ok = matches!(
            (field.r#type(), &value),
            (Type::Fixed32, Value::Fixed32(_))
                | (Type::Double, Value::Fixed64(_))
                | (Type::Enum | Type::Uint32 | Type::Int32, Value::Varint(_))
                | (Type::Bytes | Type::String, Value::Bytes(_))
                | (Type::Message, Value::Message(_))
        );
        assert!(
            ok,
            "field {} declared {:?} but encoded as {value:?}",
            field.name(),
            field.r#type()
        );
        out.push((field.name().to_string(), value));
    }
    out
}

#[test]
fn message_decodes_with_the_embedded_foxglove_schema() {
    let dir = tempfile::tempdir().unwrap();
    generate_tiny(dir.path());
    let ds = Dataset::open(dir.path()).unwrap();
    let path = dir.path().join(&ds.manifest().collections[0].file);
    let (data, schema_name, schema_data) = first_message_and_schema(&path);
    assert_eq!(schema_name, "foxglove.PointCloud");
    let fds = prost_types::FileDescriptorSet::decode(schema_data.as_slice()).unwrap();
    let fields = decode_with_descriptor(&fds, "foxglove.PointCloud", &data);
    fn values<'a>(fields: &'a [(String, Value)], name: &'a str) -> impl Iterator<Item = &'a Value> {
        fields
            .iter()
            .filter(move |(n, _)| n == name)
            .map(|(_, v)| v)
    }
    let get = |name: &'static str| values(&fields, name);
    let stride = match get("point_stride").next() {
        Some(Value::Fixed32(s)) => *s as usize,
        other => panic!("point_stride: {other:?}"),
    };
    let Some(Value::Bytes(frame_id)) = get("frame_id").next() else {
        panic!("frame_id")
    };
    assert_eq!(frame_id, b"camera_optical");
    // Field layout from the PackedElementField messages, by name.
    let mut offsets = std::collections::BTreeMap::new();
    for v in get("fields") {
        let Value::Message(f) = v else {
            panic!("fields entry")
        };
        let name = f.iter().find_map(|(n, v)| match (n.as_str(), v) {
            ("name", Value::Bytes(b)) => Some(String::from_utf8(b.clone()).unwrap()),
            _ => None,
        });
        let offset = f.iter().find_map(|(n, v)| match (n.as_str(), v) {
            ("offset", Value::Fixed32(o)) => Some(*o as usize),
            _ => None,
        });
        let numeric_type = f.iter().find_map(|(n, v)| match (n.as_str(), v) {
            ("type", Value::Varint(t)) => Some(*t),
            _ => None,
        });
        let name = name.unwrap();
        // NumericType: FLOAT32 = 7 for coordinates, UINT8 = 1 for colour channels.
        let expected_type = if ["x", "y", "z"].contains(&name.as_str()) {
            7
        } else {
            1
        };
        assert_eq!(numeric_type, Some(expected_type), "type of field {name}");
        offsets.insert(name, offset.unwrap_or(0));
    }
    assert_eq!(
        offsets.keys().cloned().collect::<Vec<_>>(),
        ["alpha", "blue", "green", "red", "x", "y", "z"]
    );
    // The pose is the identity: orientation.w (a double) = 1.
    let Some(Value::Message(pose)) = get("pose").next() else {
        panic!("pose")
    };
    let orientation = pose
        .iter()
        .find(|(n, _)| n == "orientation")
        .map(|(_, v)| v);
    let Some(Value::Message(q)) = orientation else {
        panic!("orientation")
    };
    let w = q.iter().find_map(|(n, v)| match (n.as_str(), v) {
        ("w", Value::Fixed64(bits)) => Some(f64::from_bits(*bits)),
        _ => None,
    });
    assert_eq!(w, Some(1.0));
    let Some(Value::Bytes(points)) = get("data").next() else {
        panic!("data")
    };
    // The decoded points equal what the dataset reader returns for that first frame.
    let first = ds
        .sequences(0)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .frames
        .remove(0);
    assert_eq!(points.len(), stride * first.len());
    for (i, rec) in points.chunks_exact(stride).enumerate() {
        let f = |o: usize| f32::from_le_bytes(rec[o..o + 4].try_into().unwrap());
        assert_eq!(
            [f(offsets["x"]), f(offsets["y"]), f(offsets["z"])],
            first.points[i]
        );
        let c = first.colors.as_ref().unwrap()[i];
        assert_eq!(
            [
                rec[offsets["red"]],
                rec[offsets["green"]],
                rec[offsets["blue"]]
            ],
            c
        );
    }
}

fn copy_dataset(from: &Path, to: &Path) {
    std::fs::create_dir_all(to.join("collections")).unwrap();
    for entry in std::fs::read_dir(from)
        .unwrap()
        .chain(std::fs::read_dir(from.join("collections")).unwrap())
    {
        let p = entry.unwrap().path();
        if p.is_file() {
            let rel = p.strip_prefix(from).unwrap();
            std::fs::copy(&p, to.join(rel)).unwrap();
        }
    }
}

fn read_all(dir: &Path, collection: u32) -> Result<usize, DatasetError> {
    let ds = Dataset::open(dir)?;
    let mut n = 0;
    for s in ds.sequences(collection)? {
        s?;
        n += 1;
    }
    Ok(n)
}

/// Replaces the manifest's recorded size of collection 0 so `open` passes and the reader has to
/// find the damage itself.
fn patch_manifest_size(dir: &Path, bytes: u64) {
    let path = dir.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    m["collections"][0]["bytes"] = bytes.into();
    std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
}

#[test]
fn truncated_and_corrupt_files_are_errors() {
    let base = tempfile::tempdir().unwrap();
    generate_tiny(base.path());
    let file: PathBuf = Dataset::open(base.path()).unwrap().manifest().collections[0]
        .file
        .clone()
        .into();
    let original = std::fs::read(base.path().join(&file)).unwrap();
    assert_eq!(read_all(base.path(), 0).unwrap(), 4);

    // Truncations at many points: open() notices the size; with the size patched, the reader does.
    for cut in [
        0usize,
        5,
        8,
        100,
        original.len() / 3,
        original.len() / 2,
        original.len() - 30,
        original.len() - 1,
    ] {
        let dir = tempfile::tempdir().unwrap();
        copy_dataset(base.path(), dir.path());
        std::fs::write(dir.path().join(&file), &original[..cut]).unwrap();
        let err = Dataset::open(dir.path()).unwrap_err();
        assert!(err.to_string().contains("truncated"), "{err}");
        patch_manifest_size(dir.path(), cut as u64);
        let err = read_all(dir.path(), 0).unwrap_err();
        assert!(
            matches!(err, DatasetError::Corrupt { .. }),
            "cut {cut}: {err}"
        );
    }

    // Flipped bytes across the file: CRCs, record parsing or validation catch every one.
    for k in 1..40 {
        let pos = original.len() * k / 40;
        let dir = tempfile::tempdir().unwrap();
        copy_dataset(base.path(), dir.path());
        let mut bad = original.clone();
        bad[pos] ^= 0x5a;
        std::fs::write(dir.path().join(&file), &bad).unwrap();
        match read_all(dir.path(), 0) {
            Err(DatasetError::Corrupt { reason, .. }) => assert!(!reason.is_empty()),
            Err(other) => panic!("byte {pos}: unexpected error kind {other}"),
            // A flip in a part nobody reads for data (e.g. an index's padding) may go unnoticed,
            // but then the data read must still be complete.
            Ok(n) => assert_eq!(n, 4, "byte {pos}"),
        }
    }

    // Not an MCAP at all.
    let dir = tempfile::tempdir().unwrap();
    copy_dataset(base.path(), dir.path());
    std::fs::write(dir.path().join(&file), b"hello, this is not mcap").unwrap();
    patch_manifest_size(dir.path(), 23);
    assert!(matches!(
        read_all(dir.path(), 0),
        Err(DatasetError::Corrupt { .. })
    ));

    // Missing file, broken manifest.
    let dir = tempfile::tempdir().unwrap();
    copy_dataset(base.path(), dir.path());
    std::fs::remove_file(dir.path().join(&file)).unwrap();
    assert!(matches!(
        Dataset::open(dir.path()),
        Err(DatasetError::Io { .. })
    ));
    std::fs::write(dir.path().join("manifest.json"), b"{\"format\": 3").unwrap();
    assert!(matches!(
        Dataset::open(dir.path()),
        Err(DatasetError::Manifest { .. })
    ));
}
