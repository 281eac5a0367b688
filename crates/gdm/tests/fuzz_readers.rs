//! Invariant: whatever the input — random bytes, a checkpoint damaged or doctored (bit flips,
//! truncations, extensions, every declared size overwritten with huge values, an embedded config
//! out of its limits; checksum recomputed so the content checks are reached), random or mutated
//! TOML / JSON config text — the readers never panic or abort and allocate at most a small
//! multiple of the input's size: they return a typed error, or a valid model / config that then
//! works (predict, train, replay, save and reload).
//!
//! Cases per test come from `LGDM_FUZZ_CASES` (default 5000); a long run is one command:
//! `LGDM_FUZZ_CASES=1000000 cargo test --release -p lgdm-gdm --test fuzz_readers`.
//! Allocations are counted per thread by the global allocator below; a single request above
//! 4 GiB is refused, which aborts the test binary: that is the bug this test exists to catch.
#![allow(unsafe_code)] // the counting global allocator

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::sync::OnceLock;

use lgdm_gdm::checkpoint::HEADER_LEN;
use lgdm_gdm::config::{
    MAX_CHAIN_LENGTH, MAX_CONTEXT_DEPTH, MAX_DIM, MAX_NODES, MAX_REPLAY_BUDGET,
};
use lgdm_gdm::learner::{Baseline, Learner, LearnerKind, Model};
use lgdm_gdm::{CheckpointError, Gdm, GdmConfig, Metric, PredictOptions, Sample};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::{FileFailurePersistence, TestRunner};

// ---- allocation accounting -------------------------------------------------------------------

/// The largest single allocation the test lets through.
const REFUSE_BYTES: usize = 1 << 32;

struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn track(delta: isize) {
    // `try_with`: allocations during thread teardown are simply not counted.
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSE_BYTES {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            track(layout.size() as isize);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSE_BYTES {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            track(layout.size() as isize);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        track(-(layout.size() as isize));
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > REFUSE_BYTES {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            track(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result with the peak of the bytes it allocated on this thread (the
/// result included, as long as it is alive).
fn peak_of<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let r = f();
    let peak = PEAK.with(Cell::get);
    (r, (peak - base).max(0) as usize)
}

/// What a reader may allocate for an input of `len` bytes.
fn allowance(len: usize) -> usize {
    16 * len + (1 << 20)
}

fn cases() -> u32 {
    std::env::var("LGDM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000)
}

/// Runs `test` on `cases()` values of `strategy` (shrinking a failure to a minimal case) and
/// prints how the cases ended (`--nocapture` shows it), so a run says what it exercised.
fn fuzz<S: Strategy>(
    name: &str,
    strategy: S,
    test: impl Fn(S::Value) -> Result<String, TestCaseError>,
) {
    let config = ProptestConfig {
        cases: cases(),
        max_shrink_iters: 4096,
        source_file: Some(file!()),
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource(
            "proptest-regressions",
        ))),
        ..ProptestConfig::default()
    };
    let tally = RefCell::new(BTreeMap::<String, u64>::new());
    let result = TestRunner::new(config).run(&strategy, |v| {
        let outcome = test(v)?;
        *tally.borrow_mut().entry(outcome).or_default() += 1;
        Ok(())
    });
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    let tally = tally.into_inner();
    let total: u64 = tally.values().sum();
    let parts: Vec<String> = tally.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!("{name}: {total} cases: {}", parts.join(", "));
}

// ---- base checkpoints ------------------------------------------------------------------------

fn rows(dim: usize) -> Vec<(Vec<f32>, u64, u32)> {
    (0..60u32)
        .map(|i| {
            let c = i / 20;
            let t = (i % 10) as f32;
            let x = (0..dim)
                .map(|k| {
                    c as f32 * 0.6
                        + 0.03 * t * (k as f32 + 1.0)
                        + ((i * 7 + k as u32) % 5) as f32 * 0.01
                })
                .collect();
            (x, (i / 10) as u64, c)
        })
        .collect()
}

fn samples(rows: &[(Vec<f32>, u64, u32)]) -> Vec<Sample<'_>> {
    rows.iter()
        .map(|(x, s, c)| Sample::labelled(x, *s, c * 10 + (*s % 2) as u32, *c))
        .collect()
}

/// Small trained models covering the format's branches: Mahalanobis statistics, an open
/// training sequence, K = 0 and K = 2, explicit alphas, a node cap, an untrained model.
fn bases() -> &'static [Vec<u8>] {
    static BASES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    BASES.get_or_init(|| {
        let mut out = Vec::new();
        let mut a = GdmConfig::paper_batch();
        a.seed = 3;
        let mut b = GdmConfig::paper_incremental();
        b.metric = Metric::Mahalanobis;
        b.episodic.context_depth = 1;
        b.semantic.context_depth = 1;
        b.episodic.max_nodes = Some(12);
        b.replay.chain_length = Some(4);
        let mut c = GdmConfig::paper_batch();
        c.metric = Metric::Cosine;
        c.episodic.context_depth = 0;
        c.semantic.context_depth = 0;
        c.replay.shuffle = false;
        let mut d = GdmConfig::paper_incremental();
        d.metric = Metric::Minkowski { p: 3.0 };
        d.episodic.alphas = Some(vec![0.5, 0.3, 0.2]);
        for (config, dim, open) in [(a, 3, true), (b, 2, false), (c, 4, true), (d, 3, false)] {
            let rows = rows(dim);
            let samples = samples(&rows);
            let mut gdm = Gdm::new(config, dim).unwrap();
            gdm.train(&samples).unwrap();
            gdm.end_episode();
            gdm.replay().unwrap();
            if open {
                gdm.train(&samples[..7]).unwrap();
            }
            out.push(gdm.to_bytes());
        }
        out.push(Gdm::new(GdmConfig::default(), 5).unwrap().to_bytes());
        for bytes in &out {
            Gdm::from_bytes(bytes).unwrap();
            assert!(!fields(bytes).is_empty());
        }
        out
    })
}

/// A declared value in a checkpoint: name, offset in the file, width in bytes.
#[derive(Debug, Clone)]
struct Field {
    name: String,
    at: usize,
    width: usize,
}

/// Every size, count, flag and header word of a valid checkpoint, found by walking the layout
/// of the `checkpoint` module docs.
fn fields(bytes: &[u8]) -> Vec<Field> {
    let u64_at = |p: usize| u64::from_le_bytes(bytes[p..p + 8].try_into().unwrap()) as usize;
    let u32_at = |p: usize| u32::from_le_bytes(bytes[p..p + 4].try_into().unwrap()) as usize;
    let mut out = Vec::new();
    let mut push = |name: String, at: usize, width: usize| out.push(Field { name, at, width });
    push("version".into(), 8, 4);
    push("payload length".into(), 12, 8);
    push("checksum".into(), 20, 4);
    let mut p = HEADER_LEN;
    push("config length".into(), p, 8);
    p += 8 + u64_at(p);
    push("dim".into(), p, 8);
    let dim = u64_at(p);
    p += 8;
    push("sequence flag".into(), p, 1);
    push("sequence".into(), p + 1, 8);
    push("replays".into(), p + 9, 8);
    push("learnt since replay".into(), p + 17, 8);
    p += 25;
    for net in ["episodic", "semantic"] {
        let (n, depth, levels) = (u64_at(p), u64_at(p + 16), u64_at(p + 24));
        for (k, what) in ["nodes", "dim", "depth", "levels"].iter().enumerate() {
            push(format!("{net} {what}"), p + 8 * k, 8);
        }
        p += 32;
        let stride = dim * depth;
        p += n * stride * 4 + n * 4;
        for what in ["edges", "synapses"] {
            for j in 0..n {
                push(format!("{net} node {j} {what}"), p, 4);
                p += 4 + 8 * u32_at(p);
            }
        }
        for level in 0..levels {
            for j in 0..n {
                push(format!("{net} level {level} node {j} histogram"), p, 4);
                p += 4 + 8 * u32_at(p);
            }
        }
        push(format!("{net} statistics flag"), p, 1);
        if bytes[p] == 1 {
            push(format!("{net} statistics count"), p + 1, 8);
            p += 9 + 16 * dim;
        } else {
            p += 1;
        }
        push(format!("{net} previous-node flag"), p, 1);
        push(format!("{net} previous node"), p + 1, 4);
        p += 5 + stride * 4;
    }
    assert_eq!(p, bytes.len(), "the walk must cover the checkpoint exactly");
    out
}

/// Rewrites the header's payload length and checksum so that damage reaches the content checks.
fn reseal(bytes: &mut [u8]) {
    if bytes.len() < HEADER_LEN {
        return;
    }
    let len = (bytes.len() - HEADER_LEN) as u64;
    bytes[12..20].copy_from_slice(&len.to_le_bytes());
    let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
}

// ---- the checkpoint invariant ----------------------------------------------------------------

/// Feature vectors of width `dim` to use a loaded model with.
fn probe(dim: usize) -> Vec<(Vec<f32>, u64, u32)> {
    (0..12u32)
        .map(|i| {
            let x = (0..dim)
                .map(|k| ((i as usize * 5 + k) % 7) as f32 * 0.2)
                .collect();
            (x, (i / 4) as u64, i % 3)
        })
        .collect()
}

/// Reads `input`; on success the model must be sound, save and reload to itself, and work.
/// Returns how the read ended: `model` or the error kind.
fn check_checkpoint(input: &[u8]) -> Result<String, TestCaseError> {
    let (result, peak) = peak_of(|| Gdm::from_bytes(input));
    prop_assert!(
        peak <= allowance(input.len()),
        "reading {} bytes allocated {peak} bytes",
        input.len()
    );
    let gdm = match result {
        Ok(gdm) => gdm,
        Err(e) => {
            // The error says something (and formats without panicking).
            prop_assert!(!e.to_string().is_empty());
            let kind = match e {
                CheckpointError::Io(_) => {
                    return Err(TestCaseError::fail("an I/O error from bytes in memory"));
                }
                CheckpointError::BadMagic => "bad magic",
                CheckpointError::Version { .. } => "version",
                CheckpointError::Truncated { .. } => "truncated",
                CheckpointError::Checksum { .. } => "checksum",
                CheckpointError::Corrupt(_) => "corrupt",
                CheckpointError::Config(_) => "config",
                CheckpointError::OtherLearner { .. } => "other learner",
            };
            return Ok(kind.to_string());
        }
    };
    for net in [gdm.episodic().network(), gdm.semantic().network()] {
        net.check_consistency().map_err(TestCaseError::fail)?;
    }
    gdm.config()
        .validate()
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let bytes = gdm.to_bytes();
    prop_assert!(
        bytes.len() <= input.len() + 64,
        "{} > {}",
        bytes.len(),
        input.len()
    );
    let back = Gdm::from_bytes(&bytes).map_err(|e| TestCaseError::fail(format!("reload: {e}")))?;
    prop_assert!(back == gdm, "a reloaded model differs");
    use_model(gdm)?;
    Ok("model".into())
}

/// Predicts, trains, ends an episode and replays; the result must still be a sound model.
fn use_model(mut gdm: Gdm) -> Result<(), TestCaseError> {
    let rows = probe(gdm.dim());
    let samples = samples(&rows);
    if !gdm.episodic().is_empty() && !gdm.semantic().is_empty() {
        let p = gdm
            .predict(&samples, PredictOptions::default())
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(p.len(), samples.len());
        gdm.evaluate(&samples, PredictOptions { no_context: true })
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
    }
    gdm.train(&samples)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    gdm.end_episode();
    gdm.replay()
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    gdm.predict(&samples, PredictOptions::default())
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    Ok(())
}

/// Values that stress a declared size: zero, small, the limits and just past them, powers of
/// two up to 2⁶⁴ − 1.
fn huge() -> impl Strategy<Value = u64> {
    prop_oneof![
        select(vec![
            0,
            1,
            2,
            3,
            255,
            u32::MAX as u64,
            1 << 31,
            (1 << 31) - 1,
            1 << 32,
            1 << 62,
            1 << 63,
            u64::MAX,
            MAX_DIM as u64,
            MAX_DIM as u64 + 1,
            1 << 24,
            (1 << 26) + 3,
        ]),
        0u64..1000,
        any::<u64>(),
    ]
}

#[derive(Debug, Clone)]
enum Edit {
    Flip(Index, u8),
    Byte(Index, u8),
    /// Overwrites an 8- or 4-byte window anywhere.
    Word(Index, u64, bool),
    /// Overwrites one declared value (size, count, flag, header word).
    Field(Index, u64),
    Truncate(Index),
    Extend(Vec<u8>),
    Insert(Index, Vec<u8>),
    Remove(Index, usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| Edit::Flip(i, b)),
        1 => (any::<Index>(), any::<u8>()).prop_map(|(i, v)| Edit::Byte(i, v)),
        2 => (any::<Index>(), huge(), any::<bool>()).prop_map(|(i, v, w)| Edit::Word(i, v, w)),
        4 => (any::<Index>(), huge()).prop_map(|(i, v)| Edit::Field(i, v)),
        1 => any::<Index>().prop_map(Edit::Truncate),
        1 => vec(any::<u8>(), 1..64).prop_map(Edit::Extend),
        1 => (any::<Index>(), vec(any::<u8>(), 1..16)).prop_map(|(i, b)| Edit::Insert(i, b)),
        1 => (any::<Index>(), 1usize..32).prop_map(|(i, n)| Edit::Remove(i, n)),
    ]
}

fn apply(bytes: &mut Vec<u8>, fields: &[Field], edit: &Edit) {
    let len = bytes.len();
    match edit {
        Edit::Flip(at, bit) => bytes[at.index(len)] ^= 1 << bit,
        Edit::Byte(at, v) => bytes[at.index(len)] = *v,
        Edit::Word(at, v, wide) => {
            let w = if *wide { 8 } else { 4 };
            let at = at.index(len.saturating_sub(w) + 1);
            let end = (at + w).min(len);
            bytes[at..end].copy_from_slice(&v.to_le_bytes()[..end - at]);
        }
        Edit::Field(i, v) => {
            let f = &fields[i.index(fields.len())];
            if f.at + f.width <= len {
                bytes[f.at..f.at + f.width].copy_from_slice(&v.to_le_bytes()[..f.width]);
            }
        }
        Edit::Truncate(at) => bytes.truncate(at.index(len)),
        Edit::Extend(tail) => bytes.extend_from_slice(tail),
        Edit::Insert(at, b) => {
            let at = at.index(len + 1);
            bytes.splice(at..at, b.iter().copied());
        }
        Edit::Remove(at, n) => {
            let at = at.index(len);
            bytes.drain(at..(at + n).min(len));
        }
    }
}

/// An embedded-config rewrite: the field (a JSON path) and its new value.
fn config_edit() -> impl Strategy<Value = (Vec<&'static str>, serde_json::Value)> {
    use serde_json::json;
    let paths = vec![
        vec!["replay", "chain_length"],
        vec!["replay", "budget"],
        vec!["episodic", "max_nodes"],
        vec!["semantic", "max_nodes"],
        vec!["episodic", "context_depth"],
        vec!["semantic", "context_depth"],
        vec!["episodic", "alphas"],
        vec!["episodic", "max_age"],
        vec!["semantic", "kappa"],
        vec!["metric"],
        vec!["seed"],
        vec!["preset"],
    ];
    let values = vec![
        json!(0),
        json!(1),
        json!(2),
        json!(3),
        json!(-1),
        json!(MAX_CHAIN_LENGTH),
        json!(MAX_CHAIN_LENGTH + 1),
        json!(MAX_NODES),
        json!(MAX_NODES + 1),
        json!(MAX_CONTEXT_DEPTH + 1),
        json!(1_000_000_000u64),
        json!(1u64 << 31),
        json!(1u64 << 62),
        json!(u64::MAX),
        json!(1.5),
        json!(1e300),
        json!(null),
        json!("paper_batch"),
        json!("nope"),
        json!([1.0]),
        json!([0.5, 0.3, 0.2]),
        json!({"minkowski": {"p": 0.5}}),
        json!("mahalanobis"),
        json!(true),
    ];
    (select(paths), select(values))
}

fn with_config(bytes: &[u8], path: &[&str], value: serde_json::Value) -> Vec<u8> {
    let cl = u64::from_le_bytes(bytes[HEADER_LEN..HEADER_LEN + 8].try_into().unwrap()) as usize;
    let start = HEADER_LEN + 8;
    let mut doc: serde_json::Value = serde_json::from_slice(&bytes[start..start + cl]).unwrap();
    let mut slot = &mut doc;
    for key in path {
        slot = &mut slot[*key];
    }
    *slot = value;
    let text = serde_json::to_vec(&doc).unwrap();
    let mut out = bytes[..HEADER_LEN].to_vec();
    out.extend_from_slice(&(text.len() as u64).to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&bytes[start + cl..]);
    reseal(&mut out);
    out
}

#[test]
fn random_bytes_never_panic() {
    // Framing 0: raw bytes; 1: a valid header over random bytes; 2: a valid checkpoint's prefix
    // (config, dim, …) followed by random bytes.
    let strategy = (vec(any::<u8>(), 0..600), 0u8..3);
    fuzz("random bytes", strategy, |(body, framing)| {
        let input = match framing {
            0 => body,
            1 => {
                let mut v = bases()[0][..HEADER_LEN].to_vec();
                v.extend_from_slice(&body);
                reseal(&mut v);
                v
            }
            _ => {
                let base = &bases()[body.len() % bases().len()];
                let keep = HEADER_LEN + 8 + body.len() % (base.len() - HEADER_LEN - 8);
                let mut v = base[..keep].to_vec();
                v.extend_from_slice(&body);
                reseal(&mut v);
                v
            }
        };
        check_checkpoint(&input)
    });
}

#[test]
fn mutated_checkpoints_never_panic() {
    let strategy = (any::<Index>(), vec(edit(), 1..4), prop::bool::weighted(0.9));
    fuzz(
        "mutated checkpoints",
        strategy,
        |(base, edits, resealed)| {
            let base = &bases()[base.index(bases().len())];
            let fields = fields(base);
            let mut bytes = base.clone();
            for e in &edits {
                if bytes.is_empty() {
                    break;
                }
                apply(&mut bytes, &fields, e);
            }
            if resealed {
                reseal(&mut bytes);
            }
            check_checkpoint(&bytes)
        },
    );
}

#[test]
fn embedded_configs_are_held_to_the_config_limits() {
    let strategy = (any::<Index>(), config_edit());
    fuzz("embedded configs", strategy, |(base, (path, value))| {
        let base = &bases()[base.index(bases().len())];
        let bytes = with_config(base, &path, value.clone());
        let outcome = check_checkpoint(&bytes)?;
        // A config out of its limits is a typed error, never a model.
        let limit = match path.as_slice() {
            ["replay", "chain_length"] => MAX_CHAIN_LENGTH,
            [_, "max_nodes"] => MAX_NODES,
            [_, "context_depth"] => MAX_CONTEXT_DEPTH,
            _ => usize::MAX,
        };
        if value.as_u64().is_some_and(|v| v > limit as u64) {
            prop_assert_eq!(&outcome, "config", "{:?} = {}", path, value);
        }
        if path.as_slice() == ["replay", "budget"]
            && value
                .as_f64()
                .is_some_and(|v| !(v > 0.0 && v <= MAX_REPLAY_BUDGET as f64))
        {
            prop_assert_eq!(&outcome, "config", "{:?} = {}", path, value);
        }
        Ok(outcome)
    });
}

// ---- the config invariant --------------------------------------------------------------------

/// A config document value, written out as TOML or JSON by [`to_toml`] / [`to_json`].
#[derive(Debug, Clone)]
enum V {
    Int(i128),
    Float(f64),
    Str(String),
    Bool(bool),
    Null,
    Arr(Vec<V>),
    Table(Vec<(String, V)>),
}

/// The fields of a memory section (plus one that does not exist).
const MEMORY_KEYS: &[&str] = &[
    "activation_threshold",
    "habituation_threshold",
    "context_depth",
    "beta",
    "alphas",
    "epsilon_b",
    "epsilon_n",
    "tau_b",
    "tau_n",
    "kappa",
    "removal_threshold",
    "max_age",
    "label_increment",
    "label_decrement",
    "mod_rate",
    "max_nodes",
    "bogus",
];

/// The fields of the replay section (plus one that does not exist).
const REPLAY_KEYS: &[&str] = &["chain_length", "shuffle", "budget", "bogus"];

/// Integers around every size limit, and far past them.
fn size() -> impl Strategy<Value = V> {
    prop_oneof![
        select(vec![
            0i128,
            1,
            2,
            3,
            -1,
            MAX_CONTEXT_DEPTH as i128,
            MAX_CONTEXT_DEPTH as i128 + 1,
            MAX_CHAIN_LENGTH as i128,
            MAX_CHAIN_LENGTH as i128 + 1,
            MAX_NODES as i128,
            MAX_NODES as i128 + 1,
            1_000_000_000,
            1 << 31,
            1 << 32,
            1 << 53,
            1 << 62,
            i64::MAX as i128,
            i64::MIN as i128,
            u64::MAX as i128,
            1 << 70,
        ]),
        0i128..200,
    ]
    .prop_map(V::Int)
}

/// Floats in and around the unit interval, and the extremes (NaN, ±∞, subnormal, f32 overflow).
fn float() -> impl Strategy<Value = V> {
    select(vec![
        0.0,
        -0.0,
        0.001,
        0.1,
        0.3,
        0.5,
        0.7,
        0.9,
        1.0,
        1.05,
        1.5,
        -0.5,
        2.0,
        3.0,
        1e-45,
        1e38,
        3.5e38,
        1e300,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ])
    .prop_map(V::Float)
}

fn scalar() -> impl Strategy<Value = V> {
    prop_oneof![
        size(),
        float(),
        select(vec![
            "paper_batch",
            "paper-incremental",
            "batch",
            "nope",
            "",
            "manhattan",
            "mahalanobis"
        ])
        .prop_map(|s| V::Str(s.to_string())),
        any::<bool>().prop_map(V::Bool),
        Just(V::Null),
    ]
}

fn value() -> impl Strategy<Value = V> {
    scalar().prop_recursive(3, 12, 4, |inner| {
        prop_oneof![
            vec(inner.clone(), 0..5).prop_map(V::Arr),
            vec((select(vec!["p", "minkowski", "cosine", "x"]), inner), 0..3)
                .prop_map(|kv| V::Table(kv.into_iter().map(|(k, v)| (k.to_string(), v)).collect())),
        ]
    })
}

/// A value of the type `key` expects, most of the time; anything otherwise.
fn value_for(key: &'static str) -> BoxedStrategy<V> {
    let typed = match key {
        "context_depth" | "max_nodes" | "max_age" | "chain_length" | "seed" => size().boxed(),
        "alphas" => vec(float(), 0..6).prop_map(V::Arr).boxed(),
        "shuffle" => any::<bool>().prop_map(V::Bool).boxed(),
        "budget" => prop_oneof![
            float(),
            select(vec!["all", "ALL", "some"]).prop_map(|b| V::Str(b.to_string())),
        ]
        .boxed(),
        "metric" => prop_oneof![
            select(vec![
                "manhattan",
                "euclidean",
                "cosine",
                "mahalanobis",
                "squared_euclidean"
            ])
            .prop_map(|m| V::Str(m.to_string())),
            float().prop_map(|p| V::Table(vec![(
                "minkowski".into(),
                V::Table(vec![("p".into(), p)])
            )])),
        ]
        .boxed(),
        "preset" => select(vec!["paper_batch", "paper_incremental", "batch", "nope"])
            .prop_map(|s| V::Str(s.to_string()))
            .boxed(),
        _ => float().boxed(),
    };
    prop_oneof![4 => typed, 1 => value()].boxed()
}

fn entries(keys: &'static [&'static str], max: usize) -> impl Strategy<Value = V> {
    vec(
        select(keys).prop_flat_map(|k| (Just(k.to_string()), value_for(k))),
        0..max,
    )
    .prop_map(V::Table)
}

/// A config document: top-level keys and sections, with field names and types mostly right.
fn document() -> impl Strategy<Value = Vec<(String, V)>> {
    let top = select(vec!["preset", "seed", "metric", "bogus"])
        .prop_flat_map(|k| (Just(k.to_string()), value_for(k)));
    let section = prop_oneof![
        (
            select(vec!["episodic", "semantic"]),
            entries(MEMORY_KEYS, 5)
        ),
        (Just("replay"), entries(REPLAY_KEYS, 3)),
        (Just("other"), entries(REPLAY_KEYS, 2)),
    ]
    .prop_map(|(name, table)| (name.to_string(), table));
    (vec(top, 0..3), vec(section, 0..3)).prop_map(|(mut t, s)| {
        t.extend(s);
        t
    })
}

fn float_text(f: f64, toml: bool) -> String {
    if f.is_nan() {
        if toml { "nan".into() } else { "NaN".into() }
    } else if f.is_infinite() {
        match (toml, f > 0.0) {
            (true, true) => "inf".into(),
            (true, false) => "-inf".into(),
            (false, true) => "1e999".into(),
            (false, false) => "-1e999".into(),
        }
    } else {
        format!("{f:?}")
    }
}

fn inline(v: &V, toml: bool) -> String {
    match v {
        V::Int(i) => i.to_string(),
        V::Float(f) => float_text(*f, toml),
        V::Str(s) => format!("{s:?}"),
        V::Bool(b) => b.to_string(),
        V::Null => {
            if toml {
                "\"null\"".into()
            } else {
                "null".into()
            }
        }
        V::Arr(a) => format!(
            "[{}]",
            a.iter()
                .map(|x| inline(x, toml))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        V::Table(kv) => {
            let sep = if toml { " = " } else { ": " };
            let items: Vec<String> = kv
                .iter()
                .map(|(k, v)| format!("{k:?}{sep}{}", inline(v, toml)))
                .collect();
            format!("{{{}}}", items.join(", "))
        }
    }
}

fn to_json(doc: &[(String, V)]) -> String {
    inline(&V::Table(doc.to_vec()), false)
}

fn to_toml(doc: &[(String, V)]) -> String {
    let mut out = String::new();
    for (k, v) in doc.iter().filter(|(_, v)| !matches!(v, V::Table(_))) {
        out.push_str(&format!("{k} = {}\n", inline(v, true)));
    }
    for (k, v) in doc.iter().filter(|(_, v)| matches!(v, V::Table(_))) {
        if let V::Table(kv) = v {
            out.push_str(&format!("[{k}]\n"));
            for (k, v) in kv {
                out.push_str(&format!("{k} = {}\n", inline(v, true)));
            }
        }
    }
    out
}

#[derive(Debug, Clone, Copy)]
enum Syntax {
    Toml,
    Json,
}

/// The config reader: parse, then validate.
fn read_config(text: &str, syntax: Syntax) -> Result<GdmConfig, String> {
    let config: GdmConfig = match syntax {
        Syntax::Toml => toml::from_str(text).map_err(|e| e.to_string())?,
        Syntax::Json => serde_json::from_str(text).map_err(|e| e.to_string())?,
    };
    config.validate().map_err(|e| e.to_string())?;
    Ok(config)
}

/// Reads `text`; a valid config must round-trip through both syntaxes and build a working model
/// within a fixed allocation budget. Returns how the read ended (`valid` or `rejected`).
fn check_config(text: &str, syntax: Syntax) -> Result<String, TestCaseError> {
    let (result, peak) = peak_of(|| read_config(text, syntax));
    prop_assert!(
        peak <= allowance(text.len()),
        "reading {} bytes allocated {peak} bytes",
        text.len()
    );
    let Ok(config) = result else {
        return Ok("rejected".into());
    };
    let toml_text = toml::to_string(&config).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(
        &read_config(&toml_text, Syntax::Toml).map_err(TestCaseError::fail)?,
        &config
    );
    let json_text =
        serde_json::to_string(&config).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(
        &read_config(&json_text, Syntax::Json).map_err(TestCaseError::fail)?,
        &config
    );
    let (used, peak) = peak_of(|| -> Result<(), TestCaseError> {
        let gdm = Gdm::new(config, 3).map_err(|e| TestCaseError::fail(e.to_string()))?;
        use_model(gdm)
    });
    used?;
    prop_assert!(
        peak <= 16 << 20,
        "a valid config used {peak} bytes on 3-d data"
    );
    Ok("valid".into())
}

fn mutate_text(text: &str, edits: &[(Index, u8, u8)]) -> String {
    const POOL: &[u8] = b"[]{}=,:.\"'\n #e-+0123456789naifINF_\\\t";
    let mut bytes = text.as_bytes().to_vec();
    for &(at, kind, c) in edits {
        let len = bytes.len();
        let ch = POOL[c as usize % POOL.len()];
        match kind % 4 {
            0 if len > 0 => bytes[at.index(len)] = ch,
            1 if len > 0 => {
                bytes.remove(at.index(len));
            }
            2 => bytes.insert(at.index(len + 1), ch),
            _ if len > 0 => bytes[at.index(len)] ^= 1 << (c % 7),
            _ => {}
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

/// Both syntaxes' outcomes as one label.
fn both(toml_text: &str, json_text: &str) -> Result<String, TestCaseError> {
    let t = check_config(toml_text, Syntax::Toml)?;
    let j = check_config(json_text, Syntax::Json)?;
    Ok(format!("toml {t} / json {j}"))
}

#[test]
fn generated_configs_never_panic() {
    fuzz("generated configs", document(), |doc| {
        both(&to_toml(&doc), &to_json(&doc))
    });
}

#[test]
fn mutated_configs_never_panic() {
    let strategy = (
        document(),
        vec((any::<Index>(), any::<u8>(), any::<u8>()), 1..6),
        any::<bool>(),
    );
    fuzz("mutated configs", strategy, |(doc, edits, full)| {
        let (toml_text, json_text) = if full {
            let mut c = GdmConfig::default();
            c.episodic.max_nodes = Some(500);
            c.semantic.alphas = Some(vec![0.5, 0.3, 0.2]);
            c.replay.chain_length = Some(4);
            (
                toml::to_string(&c).unwrap(),
                serde_json::to_string(&c).unwrap(),
            )
        } else {
            (to_toml(&doc), to_json(&doc))
        };
        both(
            &mutate_text(&toml_text, &edits),
            &mutate_text(&json_text, &edits),
        )
    });
}

#[test]
fn random_text_never_panics() {
    fuzz("random text", vec(any::<u8>(), 0..300), |bytes| {
        let text = String::from_utf8_lossy(&bytes);
        both(&text, &text)
    });
}

// ---- fixed cases -----------------------------------------------------------------------------

/// The allocation bound is only as good as the accounting behind it.
#[test]
fn allocations_are_counted() {
    let (v, peak) = peak_of(|| vec![1u8; 3 << 20]);
    assert!(peak >= 3 << 20, "{peak}");
    drop(v);
    let ((), peak) = peak_of(|| drop(Vec::<u8>::with_capacity(5 << 20)));
    assert!(peak >= 5 << 20, "{peak}");
    let (_, peak) = peak_of(|| 1 + 1);
    assert!(peak < 1024, "{peak}");
}

/// The reported case: a checkpoint with a valid checksum whose header says dim 2³¹.
#[test]
fn a_huge_declared_dimension_is_an_error_not_an_abort() {
    let base = &bases()[0];
    let dim_at = fields(base).iter().find(|f| f.name == "dim").unwrap().at;
    for dim in [1u64 << 31, (MAX_DIM as u64) + 1, u32::MAX as u64, u64::MAX] {
        let mut bytes = base.clone();
        bytes[dim_at..dim_at + 8].copy_from_slice(&dim.to_le_bytes());
        reseal(&mut bytes);
        let (result, peak) = peak_of(|| Gdm::from_bytes(&bytes));
        match result {
            Err(CheckpointError::Corrupt(msg)) => assert!(msg.contains("dimension"), "{msg}"),
            other => panic!("dim {dim}: expected Corrupt, got {other:?}"),
        }
        assert!(peak <= allowance(bytes.len()), "dim {dim}: {peak} bytes");
    }
}

/// Deep nesting is refused by the parsers' recursion limits, not by a stack overflow.
#[test]
fn deeply_nested_documents_are_errors() {
    for depth in [100usize, 10_000, 200_000] {
        let toml_text = format!(
            "[replay]\nchain_length = {}1{}\n",
            "[".repeat(depth),
            "]".repeat(depth)
        );
        assert!(read_config(&toml_text, Syntax::Toml).is_err());
        let toml_inline = format!("metric = {}{}\n", "{a = ".repeat(depth), "}".repeat(depth));
        assert!(read_config(&toml_inline, Syntax::Toml).is_err());
        let json_text = format!(
            "{{\"metric\": {}1{}}}",
            "[".repeat(depth),
            "]".repeat(depth)
        );
        assert!(read_config(&json_text, Syntax::Json).is_err());
    }
}

// ---- baseline model files (lgdm_gdm::learner) ------------------------------------------------

/// Trained streaming-LDA and nearest-class-mean models, of 1 and 4 features.
fn baseline_bases() -> &'static [Vec<u8>] {
    static BASES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    BASES.get_or_init(|| {
        let mut out = Vec::new();
        for kind in [LearnerKind::Slda, LearnerKind::Ncm] {
            for dim in [1, 4] {
                let rows = probe(dim);
                let mut model = Baseline::new(kind, dim).unwrap();
                model.learn(&samples(&rows)).unwrap();
                out.push(model.to_bytes());
            }
        }
        out
    })
}

/// The declared values of a baseline's file (see `lgdm_gdm::learner`'s baseline layout).
fn baseline_fields(bytes: &[u8]) -> Vec<Field> {
    let u64_at = |p: usize| u64::from_le_bytes(bytes[p..p + 8].try_into().unwrap()) as usize;
    let field = |name: &str, at, width| Field {
        name: name.into(),
        at,
        width,
    };
    let mut out = vec![
        field("version", 8, 4),
        field("payload length", 12, 8),
        field("learner", 24, 1),
        field("dim", 25, 8),
        field("pairs", 33, 8),
    ];
    let slda = bytes[24] == 1;
    let dim = u64_at(25);
    let mut p = 41 + 8 * u64_at(33);
    for head in ["category", "instance"] {
        out.push(field(head, p, 8));
        let labels = u64_at(p);
        p += 8;
        for _ in 0..labels {
            out.push(field("label count", p + 4, 8));
            p += 12 + 8 * dim;
        }
        out.push(field("head total", p, 8));
        p += 8 + if slda { 8 * dim * dim } else { 0 };
    }
    assert_eq!(p, bytes.len(), "the walk must cover the file exactly");
    out
}

#[test]
fn mutated_baseline_models_never_panic() {
    let strategy = (any::<Index>(), vec(edit(), 1..4), prop::bool::weighted(0.9));
    fuzz(
        "mutated baseline models",
        strategy,
        |(base, edits, resealed)| {
            let base = &baseline_bases()[base.index(baseline_bases().len())];
            let fields = baseline_fields(base);
            let mut bytes = base.clone();
            for e in &edits {
                if bytes.is_empty() {
                    break;
                }
                apply(&mut bytes, &fields, e);
            }
            if resealed {
                reseal(&mut bytes);
            }
            let (result, peak) = peak_of(|| Model::from_bytes(&bytes));
            prop_assert!(
                peak <= allowance(bytes.len()),
                "reading {} bytes allocated {peak} bytes",
                bytes.len()
            );
            let model = match result {
                Ok(m) => m,
                Err(e) => {
                    prop_assert!(!e.to_string().is_empty());
                    return Ok("error".into());
                }
            };
            // A model that reads back works and saves to the same bytes.
            prop_assert_eq!(&model.to_bytes(), &bytes);
            let mut model = model;
            let rows = probe(model.dim());
            let samples = samples(&rows);
            let _ = model.predict(&samples, PredictOptions::default());
            model
                .learn(&samples)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            match model.predict(&samples, PredictOptions::default()) {
                Ok(_) => Ok("model".into()),
                // Doctored means or scatter can make the covariance singular: a typed error.
                Err(lgdm_gdm::GdmError::Learner(_)) => Ok("model, singular covariance".into()),
                Err(e) => Err(TestCaseError::fail(e.to_string())),
            }
        },
    );
}
