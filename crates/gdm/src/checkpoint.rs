//! Versioned binary checkpoints of a [`Gdm`] model, written atomically.
//!
//! Layout (all integers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `LGDMCKPT` |
//! | 4 | format version (u32, currently 2; version 1 is still read) |
//! | 8 | payload length in bytes (u64) |
//! | 4 | CRC-32 (IEEE) of the payload (u32) |
//! | … | payload |
//!
//! Payload: the config as JSON (u64 length + UTF-8), `dim` (u64), the training sequence state
//! (u8 flag + u64 id), the replay counter (u64), the samples learnt since the last replay (u64;
//! not in version 1, where it reads as 0), then the episodic and the semantic network.
//! A network is: node count, dim, depth K+1 and label levels (u64 each); the n·(K+1)·D weight
//! floats (f32); n habituations (f32); per node its edges (u32 count, then u32 target + u32 age
//! each); per node its synapses (u32 count, then u32 target + u32 count each); per level and
//! node its histogram (u32 count, then u32 label + f32 count each); the Mahalanobis running
//! statistics (u8 flag, then u64 count, D f64 means, D f64 squared-deviation sums); the
//! training stream state (u8 flag + u32 previous node, (K+1)·D f32 previous best block).
//!
//! Loading checks, in order: magic, version, length (truncation), checksum, then the content
//! (config validity, sizes, every structural invariant); each failure has its own
//! [`CheckpointError`] variant. Every declared size (dimension, node, edge, synapse and
//! histogram counts) is checked against the bytes left in the payload before anything is
//! allocated for it, and the stored config against the limits of [`GdmConfig::validate`], so
//! reading allocates at most a small multiple of the file's size, whatever the file says.
//! Same model → same bytes: nothing is written in hash order.
//!
//! ```
//! use lgdm_gdm::{CheckpointError, Gdm, GdmConfig, Sample};
//! let mut gdm = Gdm::new(GdmConfig::default(), 2).unwrap();
//! let xs = [[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]];
//! let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, 0, 1, 2)).collect();
//! gdm.train(&samples).unwrap();
//! let bytes = gdm.to_bytes();
//! assert_eq!(bytes.len(), gdm.size_bytes());
//! assert_eq!(Gdm::from_bytes(&bytes).unwrap(), gdm);
//! let err = Gdm::from_bytes(&bytes[..bytes.len() - 1]).unwrap_err();
//! assert!(matches!(err, CheckpointError::Truncated { .. }));
//! ```

use std::path::Path;

use crate::config::{GdmConfig, MAX_DIM};
use crate::dual::Gdm;
use crate::error::CheckpointError;
use crate::memory::{EpisodicMemory, SemanticMemory};
use crate::metric::{Metric, RunningStats};
use crate::network::{ContextState, Edge, GammaGwr, Histogram};

/// First bytes of every checkpoint.
pub const MAGIC: [u8; 8] = *b"LGDMCKPT";
/// Format version this build writes (it also reads [`OLDEST_VERSION`] and later).
pub const VERSION: u32 = 2;
/// Oldest format version this build reads: version 1 lacks the samples learnt since the last
/// replay (read as 0).
pub const OLDEST_VERSION: u32 = 1;
/// Bytes before the payload: magic, version, payload length, checksum.
pub const HEADER_LEN: usize = 8 + 4 + 8 + 4;

struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn len(&mut self, v: usize) {
        self.u64(v as u64);
    }
    fn f32s(&mut self, v: &[f32]) {
        self.0.reserve(v.len() * 4);
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    fn f64s(&mut self, v: &[f64]) {
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
}

fn corrupt(msg: impl Into<String>) -> CheckpointError {
    CheckpointError::Corrupt(msg.into())
}

struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CheckpointError> {
        if self.buf.len() - self.pos < n {
            return Err(corrupt(format!(
                "payload ends early: need {n} bytes at offset {}",
                self.pos
            )));
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, CheckpointError> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, CheckpointError> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self) -> Result<u64, CheckpointError> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn f32(&mut self) -> Result<f32, CheckpointError> {
        Ok(f32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn flag(&mut self) -> Result<bool, CheckpointError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(corrupt(format!("flag byte {v} at offset {}", self.pos - 1))),
        }
    }
    /// Bytes left in the payload.
    fn rest(&self) -> usize {
        self.buf.len() - self.pos
    }
    /// A count of items of at least `item_bytes` each (`what` names them), checked against the
    /// rest of the payload before anything is allocated for them.
    fn count(
        &mut self,
        n: u64,
        item_bytes: usize,
        what: impl FnOnce() -> String,
    ) -> Result<usize, CheckpointError> {
        let rest = self.rest() as u64;
        match n.checked_mul(item_bytes as u64) {
            Some(total) if total <= rest => Ok(n as usize),
            _ => Err(corrupt(format!(
                "{n} {} of at least {item_bytes} bytes each declared at offset {}, but only \
                 {rest} bytes remain",
                what(),
                self.pos
            ))),
        }
    }
    fn f32s(&mut self, n: usize) -> Result<Vec<f32>, CheckpointError> {
        let bytes = self.take(n.checked_mul(4).ok_or_else(|| corrupt("size overflow"))?)?;
        Ok(bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, CheckpointError> {
        let bytes = self.take(n.checked_mul(8).ok_or_else(|| corrupt("size overflow"))?)?;
        Ok(bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }
}

fn write_network(w: &mut Writer, net: &GammaGwr) {
    w.len(net.len());
    w.len(net.dim);
    w.len(net.depth);
    w.len(net.labels.len());
    w.f32s(&net.weights);
    w.f32s(&net.habituation);
    for list in &net.edges {
        w.u32(list.len() as u32);
        for e in list {
            w.u32(e.to);
            w.u32(e.age);
        }
    }
    for list in &net.synapses {
        w.u32(list.len() as u32);
        for &(to, c) in list {
            w.u32(to);
            w.u32(c);
        }
    }
    for level in &net.labels {
        for h in level {
            w.u32(h.entries().len() as u32);
            for &(l, v) in h.entries() {
                w.u32(l);
                w.f32s(&[v]);
            }
        }
    }
    match &net.stats {
        Some(s) => {
            w.u8(1);
            w.u64(s.count);
            w.f64s(&s.mean);
            w.f64s(&s.m2);
        }
        None => w.u8(0),
    }
    match net.train_ctx.prev_node {
        Some(p) => {
            w.u8(1);
            w.u32(p);
        }
        None => {
            w.u8(0);
            w.u32(0);
        }
    }
    w.f32s(&net.train_ctx.prev_block);
}

fn read_network(
    r: &mut Reader<'_>,
    template: GammaGwr,
    name: &str,
) -> Result<GammaGwr, CheckpointError> {
    let mut net = template;
    let n = r.u64()?;
    let (dim, depth, levels) = (r.u64()?, r.u64()?, r.u64()?);
    if dim != net.dim as u64 || depth != net.depth as u64 || levels != net.labels.len() as u64 {
        return Err(corrupt(format!(
            "{name}: shape dim {dim}, depth {depth}, levels {levels} does not match the config \
             (dim {}, depth {}, levels {})",
            net.dim,
            net.depth,
            net.labels.len()
        )));
    }
    let stride = net.dim * net.depth;
    // Per node at least: its block, habituation, edge count, synapse count, a histogram count
    // per level (the template's shape is bounded by the config, so this cannot overflow).
    let node_bytes = 4 * (stride + 3 + net.labels.len());
    let n = r.count(n, node_bytes, || format!("{name} nodes"))?;
    if let Some(cap) = net.params.max_nodes
        && n > cap
    {
        return Err(corrupt(format!(
            "{name}: {n} nodes but the config caps the memory at {cap}"
        )));
    }
    net.weights = r.f32s(n * stride)?;
    net.rebuild_prefix();
    net.habituation = r.f32s(n)?;
    net.edges = Vec::with_capacity(n);
    for _ in 0..n {
        let c = r.u32()?;
        let c = r.count(c as u64, 8, || format!("{name} edges"))?;
        let mut list = Vec::with_capacity(c);
        for _ in 0..c {
            list.push(Edge {
                to: r.u32()?,
                age: r.u32()?,
            });
        }
        net.edges.push(list);
    }
    net.synapses = Vec::with_capacity(n);
    for _ in 0..n {
        let c = r.u32()?;
        let c = r.count(c as u64, 8, || format!("{name} synapses"))?;
        let mut list = Vec::with_capacity(c);
        for _ in 0..c {
            list.push((r.u32()?, r.u32()?));
        }
        net.synapses.push(list);
    }
    for level in net.labels.iter_mut() {
        level.clear();
        level.reserve_exact(n);
        for _ in 0..n {
            let c = r.u32()?;
            let c = r.count(c as u64, 8, || format!("{name} histogram entries"))?;
            let mut entries = Vec::with_capacity(c);
            for _ in 0..c {
                entries.push((r.u32()?, r.f32()?));
            }
            level.push(Histogram::from_entries(entries));
        }
    }
    let has_stats = r.flag()?;
    if has_stats != (net.metric == Metric::Mahalanobis) {
        return Err(corrupt(format!(
            "{name}: running statistics {} but metric is {:?}",
            if has_stats { "present" } else { "absent" },
            net.metric
        )));
    }
    if has_stats {
        let count = r.u64()?;
        let mean = r.f64s(net.dim)?;
        let m2 = r.f64s(net.dim)?;
        if mean.iter().chain(&m2).any(|v| !v.is_finite()) || m2.iter().any(|v| *v < 0.0) {
            return Err(corrupt(format!("{name}: invalid running statistics")));
        }
        let mut s = RunningStats::new(net.dim);
        s.count = count;
        s.mean = mean;
        s.m2 = m2;
        s.refresh();
        net.stats = Some(s);
    }
    let has_prev = r.flag()?;
    let prev = r.u32()?;
    if !has_prev && prev != 0 {
        return Err(corrupt(format!(
            "{name}: previous node {prev} stored without its flag"
        )));
    }
    let mut ctx = ContextState::new(net.dim, net.depth);
    ctx.prev_node = has_prev.then_some(prev);
    ctx.prev_block = r.f32s(stride)?;
    if ctx.prev_block.iter().any(|v| !v.is_finite()) {
        return Err(corrupt(format!("{name}: non-finite context state")));
    }
    net.train_ctx = ctx;
    net.check_consistency()
        .map_err(|e| corrupt(format!("{name}: {e}")))?;
    Ok(net)
}

impl Gdm {
    /// The checkpoint bytes of the model (see the [module docs](crate::checkpoint)).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut p = Writer(Vec::with_capacity(self.payload_estimate()));
        let config = serde_json::to_vec(&self.config).expect("config serialises to JSON");
        p.len(config.len());
        p.0.extend_from_slice(&config);
        p.len(self.dim);
        match self.sequence {
            Some(s) => {
                p.u8(1);
                p.u64(s);
            }
            None => {
                p.u8(0);
                p.u64(0);
            }
        }
        p.u64(self.replays);
        p.u64(self.learnt);
        write_network(&mut p, &self.episodic.net);
        write_network(&mut p, &self.semantic.net);
        let payload = p.0;
        let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    fn payload_estimate(&self) -> usize {
        let floats = self.episodic.net.weights.len() + self.semantic.net.weights.len();
        floats * 4 + 4096
    }

    /// Size of the checkpoint in bytes (the model size to report; serialises the model).
    pub fn size_bytes(&self) -> usize {
        self.to_bytes().len()
    }

    /// Reads a model from checkpoint bytes; every kind of damage gives a typed error, and a
    /// baseline's model file ([`crate::learner`]) is refused naming its learner.
    pub fn from_bytes(bytes: &[u8]) -> Result<Gdm, CheckpointError> {
        if bytes.starts_with(&crate::learner::BASELINE_MAGIC) {
            let found = match bytes.get(HEADER_LEN) {
                Some(1) => "slda",
                Some(2) => "ncm",
                _ => "slda or ncm",
            };
            return Err(CheckpointError::OtherLearner {
                found: found.into(),
                expected: "gdm".into(),
            });
        }
        let magic_len = bytes.len().min(MAGIC.len());
        if bytes[..magic_len] != MAGIC[..magic_len] {
            return Err(CheckpointError::BadMagic);
        }
        if bytes.len() < HEADER_LEN {
            return Err(CheckpointError::Truncated {
                expected: HEADER_LEN as u64,
                found: bytes.len() as u64,
            });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return Err(CheckpointError::Version {
                found: version,
                supported: VERSION,
            });
        }
        let len = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
        let crc = u32::from_le_bytes(bytes[20..24].try_into().expect("4 bytes"));
        let expected = (HEADER_LEN as u64).saturating_add(len);
        if (bytes.len() as u64) < expected {
            return Err(CheckpointError::Truncated {
                expected,
                found: bytes.len() as u64,
            });
        }
        if (bytes.len() as u64) > expected {
            return Err(corrupt(format!(
                "{} bytes after the declared payload",
                bytes.len() as u64 - expected
            )));
        }
        let payload = &bytes[HEADER_LEN..];
        let found = crc32fast::hash(payload);
        if found != crc {
            return Err(CheckpointError::Checksum {
                expected: crc,
                found,
            });
        }
        let mut r = Reader {
            buf: payload,
            pos: 0,
        };
        let config_len = r.u64()?;
        let config_len = r.count(config_len, 1, || "config bytes".into())?;
        let config: GdmConfig = serde_json::from_slice(r.take(config_len)?)
            .map_err(|e| corrupt(format!("config: {e}")))?;
        config.validate()?;
        let dim = r.u64()?;
        if dim == 0 || dim > MAX_DIM as u64 {
            return Err(corrupt(format!("dimension {dim} is not in 1..={MAX_DIM}")));
        }
        let dim = dim as usize;
        // Each network stores at least its stream state, (K+1)·D floats, and with Mahalanobis
        // 2·D f64 statistics: check that before `Gdm::new` allocates them.
        let per_dim = 4 * (config.episodic.context_depth + 1)
            + 4 * (config.semantic.context_depth + 1)
            + if config.metric == Metric::Mahalanobis {
                32
            } else {
                0
            };
        r.count(dim as u64, per_dim, || "input dimensions".into())?;
        let has_sequence = r.flag()?;
        let sequence = r.u64()?;
        if !has_sequence && sequence != 0 {
            return Err(corrupt(format!(
                "sequence id {sequence} stored without its flag"
            )));
        }
        let replays = r.u64()?;
        let learnt = if version >= 2 { r.u64()? } else { 0 };
        let fresh = Gdm::new(config, dim).map_err(|e| corrupt(e.to_string()))?;
        let episodic = read_network(&mut r, fresh.episodic.net, "episodic")?;
        let semantic = read_network(&mut r, fresh.semantic.net, "semantic")?;
        if r.pos != payload.len() {
            return Err(corrupt(format!(
                "{} unread bytes at the end of the payload",
                payload.len() - r.pos
            )));
        }
        Ok(Gdm {
            config: fresh.config,
            dim,
            episodic: EpisodicMemory { net: episodic },
            semantic: SemanticMemory { net: semantic },
            sequence: has_sequence.then_some(sequence),
            replays,
            learnt,
        })
    }

    /// Writes the checkpoint atomically ([`lgdm_base::fs::write_bytes`]): on error no partial file is left at
    /// `path`.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        lgdm_base::fs::write_bytes(path, &self.to_bytes())?;
        Ok(())
    }

    /// Reads a checkpoint file written by [`Gdm::save`].
    pub fn load(path: &Path) -> Result<Gdm, CheckpointError> {
        let bytes = std::fs::read(path)?;
        Gdm::from_bytes(&bytes)
    }
}
