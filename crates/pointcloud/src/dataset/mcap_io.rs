//! MCAP collection files: `foxglove.PointCloud` encoding and decoding, the collection writer
//! and the streaming, validating [`SequenceReader`].

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use foxglove::Encode;
use foxglove::messages::packed_element_field::NumericType;
use foxglove::messages::{PackedElementField, Pose as FgPose, Quaternion, Timestamp, Vector3};
use mcap::records::{MessageHeader, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use prost::Message as _;

use super::{DatasetError, Manifest, PointCloud, Sequence};
use lgdm_base::fs::AtomicFile;

/// `frame_id` of every point cloud: the turntable camera's optical frame.
pub const POINT_CLOUD_FRAME_ID: &str = "camera_optical";

/// Name, encoding and descriptor bytes of the `foxglove.PointCloud` schema.
pub fn point_cloud_schema() -> (String, String, Vec<u8>) {
    foxglove_schema::<foxglove::messages::PointCloud>()
}

/// Name, encoding and descriptor bytes of one of foxglove's well-known schemas (e.g.
/// `foxglove.PointCloud`, `foxglove.FrameTransforms`), as an MCAP schema record wants them.
pub fn foxglove_schema<T: Encode>() -> (String, String, Vec<u8>) {
    let schema = T::get_schema().expect("foxglove's well-known messages have a schema");
    (schema.name, schema.encoding, schema.data.into_owned())
}

/// An MCAP writer as every lgdm file is written: zstd chunks compressed on the calling thread
/// at zstd's default level (the same messages give the same bytes), `library` (e.g.
/// `lgdm-sim/0.1.0`) in the header. Datasets and the robot's recordings both start here.
pub fn foxglove_writer<W: std::io::Write + std::io::Seek>(
    w: W,
    library: &str,
) -> Result<mcap::Writer<W>, mcap::McapError> {
    mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .library(library)
        .create(w)
}

/// A foxglove timestamp `ns` nanoseconds after the epoch (for sim time: after the start).
pub fn foxglove_timestamp(ns: u64) -> Timestamp {
    Timestamp::new(
        u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
        (ns % 1_000_000_000) as u32,
    )
}

/// An lgdm pose (`a_from_b`) as a foxglove pose: b's origin and orientation in a.
pub fn foxglove_pose(pose: &crate::math::Pose) -> FgPose {
    let t = pose.translation.vector;
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
    FgPose {
        position: Some(Vector3 {
            x: f64::from(t.x),
            y: f64::from(t.y),
            z: f64::from(t.z),
        }),
        orientation: Some(Quaternion {
            x: f64::from(q.i),
            y: f64::from(q.j),
            z: f64::from(q.k),
            w: f64::from(q.w),
        }),
    }
}

fn field(name: &str, offset: u32, ty: NumericType) -> PackedElementField {
    PackedElementField {
        name: name.to_string(),
        offset,
        r#type: ty as i32,
    }
}

/// Encodes a cloud as a `foxglove.PointCloud` protobuf message: `x, y, z` float32 at offsets
/// 0/4/8 and, with colours, `red, green, blue, alpha` uint8 at 12..16 (stride 16, else 12).
pub fn encode_point_cloud(cloud: &PointCloud, timestamp_ns: u64) -> Vec<u8> {
    let with_color = cloud.colors.is_some();
    let stride = if with_color { 16 } else { 12 };
    let mut data = Vec::with_capacity(cloud.len() * stride);
    for (i, p) in cloud.points.iter().enumerate() {
        for v in p {
            data.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(c) = &cloud.colors {
            data.extend_from_slice(&[c[i][0], c[i][1], c[i][2], 255]);
        }
    }
    let mut fields = vec![
        field("x", 0, NumericType::Float32),
        field("y", 4, NumericType::Float32),
        field("z", 8, NumericType::Float32),
    ];
    if with_color {
        fields.extend([
            field("red", 12, NumericType::Uint8),
            field("green", 13, NumericType::Uint8),
            field("blue", 14, NumericType::Uint8),
            field("alpha", 15, NumericType::Uint8),
        ]);
    }
    let msg = foxglove::messages::PointCloud {
        timestamp: Some(foxglove_timestamp(timestamp_ns)),
        frame_id: POINT_CLOUD_FRAME_ID.to_string(),
        pose: Some(foxglove_pose(&crate::math::Pose::identity())),
        point_stride: stride as u32,
        fields,
        data: data.into(),
    };
    msg.encode_to_vec()
}

/// Decodes a `foxglove.PointCloud` message written by [`encode_point_cloud`] (or any message
/// with float32 `x, y, z` and optional uint8 `red, green, blue` fields).
pub fn decode_point_cloud(bytes: &[u8]) -> Result<PointCloud, String> {
    let msg = foxglove::messages::PointCloud::decode(bytes)
        .map_err(|e| format!("protobuf decode: {e}"))?;
    let stride = msg.point_stride as usize;
    let find = |name: &str| msg.fields.iter().find(|f| f.name == name);
    let mut xyz = [0usize; 3];
    for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
        let f = find(name).ok_or_else(|| format!("point field `{name}` missing"))?;
        if f.r#type != NumericType::Float32 as i32 {
            return Err(format!("point field `{name}` is not float32"));
        }
        xyz[k] = f.offset as usize;
        if xyz[k] + 4 > stride {
            return Err(format!(
                "point field `{name}` lies outside the stride {stride}"
            ));
        }
    }
    let mut rgb = [0usize; 3];
    let mut with_color = true;
    for (k, name) in ["red", "green", "blue"].into_iter().enumerate() {
        match find(name) {
            Some(f) if f.r#type == NumericType::Uint8 as i32 && (f.offset as usize) < stride => {
                rgb[k] = f.offset as usize;
            }
            Some(_) => {
                return Err(format!(
                    "colour field `{name}` is not uint8 inside the stride"
                ));
            }
            None => with_color = false,
        }
    }
    if stride == 0 || msg.data.len() % stride != 0 {
        return Err(format!(
            "data length {} is not a multiple of the stride {stride}",
            msg.data.len()
        ));
    }
    let n = msg.data.len() / stride;
    let mut points = Vec::with_capacity(n);
    let mut colors = with_color.then(|| Vec::with_capacity(n));
    let f32_at =
        |rec: &[u8], o: usize| f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
    for (i, rec) in msg.data.chunks_exact(stride).enumerate() {
        let p = [
            f32_at(rec, xyz[0]),
            f32_at(rec, xyz[1]),
            f32_at(rec, xyz[2]),
        ];
        if !p.iter().all(|v| v.is_finite()) {
            return Err(format!("point {i} has a non-finite coordinate"));
        }
        points.push(p);
        if let Some(c) = colors.as_mut() {
            c.push([rec[rgb[0]], rec[rgb[1]], rec[rgb[2]]]);
        }
    }
    Ok(PointCloud::new(points, colors))
}

/// Labels of one object sequence, as stored in its channel's metadata.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ChannelLabels {
    pub collection: u32,
    pub category: u32,
    pub instance: u32,
    pub frames: usize,
}

impl ChannelLabels {
    fn to_metadata(&self, category_name: &str, instance_name: &str) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("collection".to_string(), self.collection.to_string()),
            ("category".to_string(), self.category.to_string()),
            ("category_name".to_string(), category_name.to_string()),
            ("instance".to_string(), self.instance.to_string()),
            ("instance_name".to_string(), instance_name.to_string()),
            ("frames".to_string(), self.frames.to_string()),
        ])
    }

    fn from_metadata(m: &BTreeMap<String, String>) -> Result<Self, String> {
        let num = |key: &str| -> Result<u64, String> {
            m.get(key)
                .ok_or_else(|| format!("channel metadata lacks `{key}`"))?
                .parse::<u64>()
                .map_err(|e| format!("channel metadata `{key}`: {e}"))
        };
        let small = |key: &str| -> Result<u32, String> {
            u32::try_from(num(key)?).map_err(|_| format!("channel metadata `{key}` too large"))
        };
        Ok(Self {
            collection: small("collection")?,
            category: small("category")?,
            instance: small("instance")?,
            frames: usize::try_from(num("frames")?).map_err(|_| "frames too large".to_string())?,
        })
    }
}

/// Writes one collection file: a temp file that becomes `path` only on
/// [`CollectionWriter::finish`]; dropped or [abandoned](CollectionWriter::abandon) before, it
/// is removed.
pub(crate) struct CollectionWriter {
    writer: mcap::Writer<AtomicFile>,
    schema_id: u16,
    path: PathBuf,
    nanos_per_frame: u64,
}

impl CollectionWriter {
    pub fn create(
        path: &Path,
        fps: f32,
        metadata: BTreeMap<String, String>,
    ) -> Result<Self, DatasetError> {
        let file =
            AtomicFile::with_capacity(path, 1 << 20).map_err(|e| DatasetError::io(path, e))?;
        let mcap_err = |e: mcap::McapError| DatasetError::Corrupt {
            path: path.to_path_buf(),
            reason: format!("writing MCAP: {e}"),
        };
        let library = concat!("lgdm-pointcloud/", env!("CARGO_PKG_VERSION"));
        let mut writer = foxglove_writer(file, library).map_err(mcap_err)?;
        let (name, encoding, data) = point_cloud_schema();
        let schema_id = writer
            .add_schema(&name, &encoding, &data)
            .map_err(mcap_err)?;
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "lgdm.collection".into(),
                metadata,
            })
            .map_err(mcap_err)?;
        Ok(Self {
            writer,
            schema_id,
            path: path.to_path_buf(),
            nanos_per_frame: (1e9 / f64::from(fps)).round() as u64,
        })
    }

    fn err(&self, e: mcap::McapError) -> DatasetError {
        DatasetError::Corrupt {
            path: self.path.clone(),
            reason: format!("writing MCAP: {e}"),
        }
    }

    /// Adds a channel for one object sequence; returns its id.
    pub fn add_sequence(
        &mut self,
        labels: &ChannelLabels,
        category_name: &str,
        instance_name: &str,
    ) -> Result<u16, DatasetError> {
        let topic = format!("/{category_name}/{instance_name}");
        let meta = labels.to_metadata(category_name, instance_name);
        self.writer
            .add_channel(self.schema_id, &topic, "protobuf", &meta)
            .map_err(|e| self.err(e))
    }

    /// Writes frame `frame` of the sequence on `channel`.
    pub fn write_frame(
        &mut self,
        channel: u16,
        frame: u32,
        cloud: &PointCloud,
    ) -> Result<(), DatasetError> {
        let t = u64::from(frame) * self.nanos_per_frame;
        let data = encode_point_cloud(cloud, t);
        self.writer
            .write_to_known_channel(
                &MessageHeader {
                    channel_id: channel,
                    sequence: frame,
                    log_time: t,
                    publish_time: t,
                },
                &data,
            )
            .map_err(|e| self.err(e))
    }

    /// Finishes the file and renames it into place; returns its size in bytes.
    pub fn finish(mut self) -> Result<u64, DatasetError> {
        self.writer.finish().map_err(|e| self.err(e))?;
        self.writer
            .into_inner()
            .commit()
            .map_err(|e| DatasetError::io(&self.path, e))
    }

    /// Removes the temp file (after a failure).
    pub fn abandon(self) {
        drop(self);
    }
}

/// The longest MCAP record (or decompressed chunk record) a collection file of `file_len` bytes
/// may hold: 64 × its size (point clouds compress far less), between 1 MiB and 256 MiB. Bounds
/// what a corrupt length field makes the reader allocate.
fn record_length_limit(file_len: u64) -> usize {
    usize::try_from(file_len.saturating_mul(64))
        .unwrap_or(usize::MAX)
        .clamp(1 << 20, 256 << 20)
}

/// What the reader checks each sequence against.
#[derive(Debug, Clone)]
struct Expected {
    collection: u32,
    frames: usize,
    /// Category of each instance.
    categories: Vec<u32>,
}

/// Streams the sequences of one collection file, validating as it reads (see
/// [`super::Dataset::sequences`]). Holds one sequence in memory at a time.
pub struct SequenceReader {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    expected: Expected,
    point_cloud_schemas: Vec<u16>,
    channels: BTreeMap<u16, ChannelLabels>,
    current: Option<(u16, Sequence)>,
    seen: Vec<bool>,
    done: bool,
    /// Bytes of the file not yet handed to the MCAP reader (reads never ask for more).
    unread: u64,
}

impl std::fmt::Debug for SequenceReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SequenceReader")
            .field("path", &self.path)
            .field("collection", &self.expected.collection)
            .finish_non_exhaustive()
    }
}

/// What the MCAP reader did next.
enum Step {
    /// The file ended after its footer.
    End,
    /// The file is not valid MCAP (or a record is unreadable).
    Invalid(String),
    /// The reader needs this many more bytes.
    Read(usize),
    /// A record, parsed.
    Record(Owned),
}

/// The reader's next event, with records checked ([`check_record_lengths`]) and parsed.
fn next_step(reader: &mut LinearReader) -> Step {
    match reader.next_event() {
        None => Step::End,
        Some(Err(mcap::McapError::UnexpectedEof)) => {
            Step::Invalid("truncated: the file ends before the MCAP footer".into())
        }
        Some(Err(e)) => Step::Invalid(format!("invalid MCAP: {e}")),
        Some(Ok(LinearReadEvent::ReadRequest(n))) => Step::Read(n),
        Some(Ok(LinearReadEvent::Record { opcode, data })) => {
            if let Err(reason) = check_record_lengths(opcode, data) {
                return Step::Invalid(format!("invalid MCAP record: {reason}"));
            }
            Step::Record(match mcap::parse_record(opcode, data) {
                Err(e) => return Step::Invalid(format!("invalid MCAP record: {e}")),
                Ok(Record::Schema { header, .. }) => Owned::Schema {
                    id: header.id,
                    ok: header.name == "foxglove.PointCloud" && header.encoding == "protobuf",
                    name: header.name,
                },
                Ok(Record::Channel(ch)) => Owned::Channel {
                    id: ch.id,
                    schema: ch.schema_id,
                    encoding: ch.message_encoding.clone(),
                    labels: ChannelLabels::from_metadata(&ch.metadata),
                },
                Ok(Record::Message { header, data }) => Owned::Message {
                    channel: header.channel_id,
                    frame: header.sequence,
                    cloud: decode_point_cloud(&data),
                },
                Ok(_) => Owned::Other,
            })
        }
    }
}

/// One record, copied out of the reader's buffer.
enum Owned {
    Schema {
        id: u16,
        ok: bool,
        name: String,
    },
    Channel {
        id: u16,
        schema: u16,
        encoding: String,
        labels: Result<ChannelLabels, String>,
    },
    Message {
        channel: u16,
        frame: u32,
        cloud: Result<PointCloud, String>,
    },
    Other,
}

impl SequenceReader {
    pub(crate) fn open(
        path: &Path,
        collection: u32,
        manifest: &Manifest,
    ) -> Result<Self, DatasetError> {
        let file = File::open(path).map_err(|e| DatasetError::io(path, e))?;
        let unread = file
            .metadata()
            .map_err(|e| DatasetError::io(path, e))?
            .len();
        let options = LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_validate_summary_section_crc(true)
            .with_record_length_limit(record_length_limit(unread));
        Ok(Self {
            path: path.to_path_buf(),
            file,
            reader: LinearReader::new_with_options(options),
            expected: Expected {
                collection,
                frames: manifest.frames_per_sequence,
                categories: manifest.instances.iter().map(|i| i.category).collect(),
            },
            point_cloud_schemas: Vec::new(),
            channels: BTreeMap::new(),
            current: None,
            seen: vec![false; manifest.instances.len()],
            done: false,
            unread,
        })
    }

    fn corrupt(&self, reason: impl Into<String>) -> DatasetError {
        DatasetError::Corrupt {
            path: self.path.clone(),
            reason: reason.into(),
        }
    }

    fn finish_current(&mut self) -> Result<Option<Sequence>, DatasetError> {
        let Some((_, seq)) = self.current.take() else {
            return Ok(None);
        };
        if seq.frames.len() != self.expected.frames {
            return Err(self.corrupt(format!(
                "sequence of instance {} has {} frames, expected {}",
                seq.instance,
                seq.frames.len(),
                self.expected.frames
            )));
        }
        Ok(Some(seq))
    }

    fn advance(&mut self) -> Result<Option<Sequence>, DatasetError> {
        loop {
            let mut read_request = None;
            // The `mcap` reader is guarded: with overflow checks (debug builds) version 0.26
            // panics on a record longer than its uncompressed chunk (release builds wrap and
            // fail later). A panic there is a corrupt file, not a crash.
            let step = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                next_step(&mut self.reader)
            }))
            .unwrap_or_else(|panic| {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                Step::Invalid(format!("invalid MCAP (the reader failed: {what})"))
            });
            let owned = match step {
                Step::End => {
                    if let Some(seq) = self.finish_current()? {
                        return Ok(Some(seq));
                    }
                    if let Some(missing) = self.seen.iter().position(|&s| !s) {
                        return Err(self.corrupt(format!("no sequence for instance {missing}")));
                    }
                    return Ok(None);
                }
                Step::Invalid(reason) => return Err(self.corrupt(reason)),
                Step::Read(n) => {
                    read_request = Some(n);
                    Owned::Other
                }
                Step::Record(owned) => owned,
            };
            if let Some(n) = read_request {
                // Reads of 64 KiB to 16 MiB, never beyond the end of the file: a corrupt length
                // cannot make the buffer grow past the file's size (0 bytes left reads 0:
                // the end of the file).
                let want = n
                    .clamp(64 << 10, 16 << 20)
                    .min(usize::try_from(self.unread).unwrap_or(usize::MAX));
                let buf = self.reader.insert(want);
                let got = self
                    .file
                    .read(buf)
                    .map_err(|e| DatasetError::io(&self.path, e))?;
                self.reader.notify_read(got);
                self.unread = self.unread.saturating_sub(got as u64);
                continue;
            }
            match owned {
                Owned::Other => {}
                Owned::Schema { id, ok, name } => {
                    if ok {
                        self.point_cloud_schemas.push(id);
                    } else {
                        return Err(self.corrupt(format!(
                            "schema `{name}` is not protobuf foxglove.PointCloud"
                        )));
                    }
                }
                Owned::Channel {
                    id,
                    schema,
                    encoding,
                    labels,
                } => {
                    if self.channels.contains_key(&id) {
                        continue; // repeated in the summary section
                    }
                    if !self.point_cloud_schemas.contains(&schema) || encoding != "protobuf" {
                        return Err(self.corrupt(format!(
                            "channel {id} is not a protobuf foxglove.PointCloud channel"
                        )));
                    }
                    let labels = labels.map_err(|r| self.corrupt(format!("channel {id}: {r}")))?;
                    let e = &self.expected;
                    if labels.collection != e.collection {
                        return Err(self.corrupt(format!(
                            "channel {id} belongs to collection {}, expected {}",
                            labels.collection, e.collection
                        )));
                    }
                    match e.categories.get(labels.instance as usize) {
                        None => {
                            return Err(self.corrupt(format!(
                                "channel {id}: instance {} not in the manifest ({} instances)",
                                labels.instance,
                                e.categories.len()
                            )));
                        }
                        Some(&c) if c != labels.category => {
                            return Err(self.corrupt(format!(
                                "channel {id}: instance {} has category {}, the manifest says {c}",
                                labels.instance, labels.category
                            )));
                        }
                        Some(_) => {}
                    }
                    if labels.frames != e.frames {
                        return Err(self.corrupt(format!(
                            "channel {id}: {} frames, the manifest says {}",
                            labels.frames, e.frames
                        )));
                    }
                    self.channels.insert(id, labels);
                }
                Owned::Message {
                    channel,
                    frame,
                    cloud,
                } => {
                    let Some(labels) = self.channels.get(&channel).cloned() else {
                        return Err(self.corrupt(format!("message on unknown channel {channel}")));
                    };
                    let cloud = cloud.map_err(|r| {
                        self.corrupt(format!("instance {} frame {frame}: {r}", labels.instance))
                    })?;
                    let mut finished = None;
                    if self.current.as_ref().is_some_and(|(c, _)| *c != channel) {
                        finished = self.finish_current()?;
                    }
                    if self.current.is_none() {
                        let seen = &mut self.seen[labels.instance as usize];
                        if *seen {
                            return Err(self.corrupt(format!(
                                "instance {} appears in more than one run of messages",
                                labels.instance
                            )));
                        }
                        *seen = true;
                        self.current = Some((
                            channel,
                            Sequence {
                                collection: labels.collection,
                                category: labels.category,
                                instance: labels.instance,
                                // Capped: the count is the manifest's, not yet the file's.
                                frames: Vec::with_capacity(self.expected.frames.min(1024)),
                            },
                        ));
                    }
                    let (have, instance) = self
                        .current
                        .as_ref()
                        .map(|(_, s)| (s.frames.len(), s.instance))
                        .expect("just set");
                    if frame as usize != have {
                        return Err(self.corrupt(format!(
                            "instance {instance}: frame {frame} arrives where frame {have} was expected"
                        )));
                    }
                    if have >= self.expected.frames {
                        return Err(self.corrupt(format!("instance {instance}: too many frames")));
                    }
                    let (_, seq) = self.current.as_mut().expect("just set");
                    seq.frames.push(cloud);
                    if finished.is_some() {
                        return Ok(finished);
                    }
                }
            }
        }
    }
}

/// One field of an MCAP record, for [`check_record_lengths`].
#[derive(Clone, Copy)]
enum Field {
    /// `n` bytes.
    Fixed(usize),
    /// `u32` length + bytes (a string or the schema's data).
    Bytes32,
    /// `u64` length + bytes (an attachment's data).
    Bytes64,
    /// `u32` byte length + string → string entries.
    StringMap,
    /// `u32` byte length + fixed-size entries (maps of integers, index arrays).
    Entries,
}

/// Checks that every length declared inside an MCAP record fits in the record's bytes, so
/// that parsing it allocates no more than the record holds. (`mcap::parse_record` trusts
/// string lengths: a corrupt one asks for up to 4 GiB, and a short attachment record panics.)
fn check_record_lengths(opcode: u8, data: &[u8]) -> Result<(), String> {
    use Field::*;
    let fields: &[Field] = match opcode {
        0x01 => &[Bytes32, Bytes32],                                 // header
        0x02 => &[Fixed(20)],                                        // footer
        0x03 => &[Fixed(2), Bytes32, Bytes32, Bytes32],              // schema
        0x04 => &[Fixed(4), Bytes32, Bytes32, StringMap],            // channel
        0x05 => &[Fixed(22)],                                        // message
        0x06 => &[Fixed(28), Bytes32, Fixed(8)],                     // chunk
        0x07 => &[Fixed(2), Entries],                                // message index
        0x08 => &[Fixed(32), Entries, Fixed(8), Bytes32, Fixed(16)], // chunk index
        0x09 => &[Fixed(16), Bytes32, Bytes32, Bytes64, Fixed(4)],   // attachment
        0x0a => &[Fixed(40), Bytes32, Bytes32],                      // attachment index
        0x0b => &[Fixed(42), Entries],                               // statistics
        0x0c => &[Bytes32, StringMap],                               // metadata
        0x0d => &[Fixed(16), Bytes32],                               // metadata index
        0x0e => &[Fixed(17)],                                        // summary offset
        0x0f => &[Fixed(4)],                                         // data end
        _ => &[],
    };
    let short = |what: &str, need: u64, at: usize| {
        format!(
            "opcode {opcode:#04x}: {what} of {need} bytes at offset {at} overruns the {}-byte record",
            data.len()
        )
    };
    let len_at = |at: usize, width: usize| -> Result<u64, String> {
        let b = data
            .get(at..at + width)
            .ok_or_else(|| short("a length field", width as u64, at))?;
        Ok(if width == 4 {
            u64::from(u32::from_le_bytes(b.try_into().expect("4 bytes")))
        } else {
            u64::from_le_bytes(b.try_into().expect("8 bytes"))
        })
    };
    // Skips `n` bytes from `at` within `end`.
    let skip = |at: usize, n: u64, end: usize, what: &str| -> Result<usize, String> {
        match usize::try_from(n).ok().and_then(|n| at.checked_add(n)) {
            Some(next) if next <= end => Ok(next),
            _ => Err(short(what, n, at)),
        }
    };
    let mut at = 0usize;
    for &field in fields {
        at = match field {
            Fixed(n) => skip(at, n as u64, data.len(), "a fixed field")?,
            Bytes32 => skip(at + 4, len_at(at, 4)?, data.len(), "a string")?,
            Bytes64 => skip(at + 8, len_at(at, 8)?, data.len(), "a byte array")?,
            Entries => skip(at + 4, len_at(at, 4)?, data.len(), "an index")?,
            StringMap => {
                let end = skip(at + 4, len_at(at, 4)?, data.len(), "a map")?;
                let mut p = at + 4;
                while p < end {
                    for _ in 0..2 {
                        let n = len_at(p, 4)?;
                        p = skip(p + 4, n, end, "a map entry")?;
                    }
                }
                end
            }
        };
    }
    Ok(())
}

impl Iterator for SequenceReader {
    type Item = Result<Sequence, DatasetError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.advance() {
            Ok(Some(seq)) => Some(Ok(seq)),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn string(s: &str) -> Vec<u8> {
        let mut b = (s.len() as u32).to_le_bytes().to_vec();
        b.extend_from_slice(s.as_bytes());
        b
    }

    #[test]
    fn record_lengths_are_checked_before_parsing() {
        // A channel as the writer makes it.
        let mut map = string("frames");
        map.extend(string("2"));
        let mut channel = vec![1, 0, 1, 0];
        channel.extend(string("/mug/mug_01"));
        channel.extend(string("protobuf"));
        channel.extend((map.len() as u32).to_le_bytes());
        channel.extend(&map);
        assert_eq!(check_record_lengths(0x04, &channel), Ok(()));
        assert!(mcap::parse_record(0x04, &channel).is_ok());
        // Its topic claiming 4 GiB: `mcap::parse_record` would allocate that much.
        let mut huge = channel.clone();
        huge[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = check_record_lengths(0x04, &huge).unwrap_err();
        assert!(err.contains("4294967295 bytes"), "{err}");
        // A map entry running past the map.
        let mut entry = channel.clone();
        let at = channel.len() - map.len();
        entry[at..at + 4].copy_from_slice(&1000u32.to_le_bytes());
        assert!(check_record_lengths(0x04, &entry).is_err());
        // An attachment ending right after its data length (no CRC): `mcap::parse_record`
        // 0.26 slices past its end and panics.
        let mut attachment = vec![0u8; 16];
        attachment.extend(string(""));
        attachment.extend(string(""));
        attachment.extend(0u64.to_le_bytes());
        assert!(check_record_lengths(0x09, &attachment).is_err());
        attachment.extend(0u32.to_le_bytes());
        assert_eq!(check_record_lengths(0x09, &attachment), Ok(()));
        assert!(mcap::parse_record(0x09, &attachment).is_ok());
    }

    #[test]
    fn the_record_length_limit_follows_the_file_size() {
        assert_eq!(record_length_limit(0), 1 << 20);
        assert_eq!(record_length_limit(100 << 10), 6400 << 10);
        assert_eq!(record_length_limit(1 << 40), 256 << 20);
    }
}
