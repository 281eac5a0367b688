//! Every reader of outside bytes in this crate, given random or mutated input, returns an error
//! or a valid result: it never panics or aborts, and no allocation (nor all live allocations
//! together) exceeds a bound tied to the input's size.
//!
//! Readers: MCAP collection files (`Dataset::open` + `sequences`, and `decode_point_cloud`),
//! `manifest.json` (`Dataset::open`, then every sequence and `FeatureTable::check_dataset`),
//! `.npz` (`npz::read_npz`, `npz::parse_npy`, `FeatureTable::read_npz` / `read_npz_exact`),
//! meshes (`import::load_mesh`: OBJ, ASCII and binary STL, ASCII and binary PLY) and the
//! Cornell files (`read_rectangles`, `RgbImage::read_png`, `read_depth_tiff`). Inputs start from
//! valid files these readers accept and are mutated (bit flips, interesting integers, cut,
//! repeated and inserted ranges, huge numbers in text, huge counts in headers), or are random.
//!
//! `LGDM_FUZZ_CASES` sets the cases per input family (default 1000: about 21,000 cases, 2 s in
//! release on two idle cores, up to 15 s on busy ones; families of cheap inputs run 2 or 4
//! times as many), `LGDM_FUZZ_SEED` the seed (default 0). A long run (4.2 million cases, about
//! 14 minutes):
//!
//! ```text
//! LGDM_FUZZ_CASES=200000 cargo test --release -p lgdm-pointcloud --test fuzz_readers -- --nocapture
//! ```
//!
//! A finding (panic, or an allocation over the bound) fails the test with the case's seed and
//! number, and its input is saved under `$TMPDIR/lgdm-fuzz-findings/`. An allocation larger
//! than 1 GiB is refused, which aborts the process after printing the case. To see where a
//! case allocates, replay it alone with a lower refusal limit and a backtrace:
//! `LGDM_FUZZ_CASE=<n> LGDM_FUZZ_HARD_LIMIT=<bytes> RUST_BACKTRACE=1`.
#![allow(unsafe_code)] // The counting global allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use lgdm_pointcloud::PointCloud;
use lgdm_pointcloud::dataset::{
    Dataset, DatasetSpec, MANIFEST_FILE, Manifest, decode_point_cloud, encode_point_cloud,
    generate, point_cloud_schema, standard_collections,
};
use lgdm_pointcloud::features::FeatureTable;
use lgdm_pointcloud::grasp::GraspRectangle;
use lgdm_pointcloud::grasp::cornell::{read_rectangles, write_rectangles};
use lgdm_pointcloud::image::{RgbImage, read_depth_tiff, write_depth_tiff};
use lgdm_pointcloud::import::load_mesh;
use lgdm_pointcloud::npz::{NpyRef, npy_bytes, parse_npy, read_npz, write_npz};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

// ---------------------------------------------------------------------------------------------
// Allocation accounting: per thread, only while a reader runs.

/// Allocations above this are refused (the process aborts, with a backtrace under
/// `RUST_BACKTRACE=1`) rather than attempted: 1 GiB, or `LGDM_FUZZ_HARD_LIMIT` bytes (set it to
/// the bound, with `LGDM_FUZZ_CASE`, to see where a case over-allocates).
static HARD_LIMIT: AtomicUsize = AtomicUsize::new(1 << 30);

thread_local! {
    static TRACKING: Cell<bool> = const { Cell::new(false) };
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
    static BIGGEST: Cell<usize> = const { Cell::new(0) };
    static CASE: Cell<(&'static str, u64)> = const { Cell::new(("", 0)) };
}

struct Counting;

fn write_usize(out: &mut [u8; 20], mut v: usize) -> &[u8] {
    let mut i = out.len();
    loop {
        i -= 1;
        out[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            return &out[i..];
        }
    }
}

/// Accounts `size` new bytes; false if the allocation must be refused.
fn track_alloc(size: usize) -> bool {
    let tracking = TRACKING.try_with(Cell::get).unwrap_or(false);
    if !tracking {
        return true;
    }
    let _ = BIGGEST.try_with(|b| b.set(b.get().max(size)));
    let _ = LIVE.try_with(|l| {
        let live = l.get().saturating_add(size as isize);
        l.set(live);
        let _ = PEAK.try_with(|p| p.set(p.get().max(live)));
    });
    if size > HARD_LIMIT.load(Ordering::Relaxed) {
        // Report without allocating, then refuse: the process aborts.
        let (target, case) = CASE.try_with(Cell::get).unwrap_or(("?", 0));
        let mut buf = [0u8; 20];
        let mut err = std::io::stderr();
        let _ = err.write_all(b"\nfuzz_readers: reader `");
        let _ = err.write_all(target.as_bytes());
        let _ = err.write_all(b"`, case ");
        let _ = err.write_all(write_usize(&mut buf, case as usize));
        let _ = err.write_all(b": an allocation of ");
        let _ = err.write_all(write_usize(&mut buf, size));
        let _ = err.write_all(b" bytes (refused)\n");
        return false;
    }
    true
}

fn track_free(size: usize) {
    if TRACKING.try_with(Cell::get).unwrap_or(false) {
        let _ = LIVE.try_with(|l| l.set(l.get().saturating_sub(size as isize)));
    }
}

// SAFETY: forwards to `System` unchanged; the bookkeeping touches only const-initialised
// thread-locals (no allocation, no destructor) and never unwinds.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !track_alloc(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !track_alloc(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        track_free(layout.size());
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !track_alloc(new_size) {
            return std::ptr::null_mut();
        }
        track_free(layout.size());
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

// ---------------------------------------------------------------------------------------------
// The harness.

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.trim().replace('_', "").parse().ok())
        .unwrap_or(default)
}

/// Cases per input family (`LGDM_FUZZ_CASES`, default 1000).
fn cases() -> u64 {
    env_u64("LGDM_FUZZ_CASES", 1000)
}

/// Only this case of each family (`LGDM_FUZZ_CASE`), to replay a finding.
fn only_case() -> Option<u64> {
    std::env::var("LGDM_FUZZ_CASE").ok()?.trim().parse().ok()
}

fn base_seed() -> u64 {
    env_u64("LGDM_FUZZ_SEED", 0)
}

fn case_rng(family: &str, case: u64) -> ChaCha8Rng {
    let mut h = 0xcbf2_9ce4_8422_2325u64 ^ base_seed();
    for b in family.bytes().chain(case.to_le_bytes()) {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    ChaCha8Rng::seed_from_u64(h)
}

thread_local! {
    static PANIC_MESSAGE: RefCell<Option<String>> = const { RefCell::new(None) };
    static CAPTURE_PANICS: Cell<bool> = const { Cell::new(false) };
}

/// Panics inside readers are recorded (message and location), not printed; others print.
fn install_panic_hook() {
    static ONCE: OnceLock<()> = OnceLock::new();
    ONCE.get_or_init(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if CAPTURE_PANICS.with(Cell::get) {
                let msg = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                let at = info
                    .location()
                    .map(|l| format!("{}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                PANIC_MESSAGE.with(|m| *m.borrow_mut() = Some(format!("panic at {at}: {msg}")));
            } else {
                default(info);
            }
        }));
    });
}

/// Bound on allocations while reading `len` input bytes: `fixed + per_byte × len`.
#[derive(Clone, Copy)]
struct Bound {
    fixed: usize,
    per_byte: usize,
}

impl Bound {
    fn of(self, len: usize) -> usize {
        self.fixed.saturating_add(self.per_byte.saturating_mul(len))
    }
}

/// One reader's run: counts cases and collects findings (first inputs of each kind saved).
struct Fuzz {
    target: &'static str,
    started: Instant,
    cases: u64,
    errors: u64,
    /// Finding kind → (count, first case, saved input).
    findings: BTreeMap<String, (u64, u64, PathBuf)>,
    peak_ratio: f64,
}

impl Fuzz {
    fn new(target: &'static str) -> Fuzz {
        install_panic_hook();
        if let Some(limit) = std::env::var("LGDM_FUZZ_HARD_LIMIT")
            .ok()
            .and_then(|v| v.trim().parse().ok())
        {
            HARD_LIMIT.store(limit, Ordering::Relaxed);
        }
        Fuzz {
            target,
            started: Instant::now(),
            cases: 0,
            errors: 0,
            findings: BTreeMap::new(),
            peak_ratio: 0.0,
        }
    }

    /// Runs `read` on one input (`input` is what gets saved on a finding; `limit` the
    /// allocation bound). `read` returns Ok(()) for a valid result, Err(()) for a reader error,
    /// and panics (with `invalid:` in the message) for an invalid `Ok`.
    fn case(
        &mut self,
        case: u64,
        input: &[u8],
        ext: &str,
        limit: usize,
        read: impl FnOnce() -> Result<(), ()>,
    ) {
        if only_case().is_some_and(|only| only != case) {
            return;
        }
        self.cases += 1;
        CASE.with(|c| c.set((self.target, case)));
        LIVE.with(|l| l.set(0));
        PEAK.with(|p| p.set(0));
        BIGGEST.with(|b| b.set(0));
        PANIC_MESSAGE.with(|m| m.borrow_mut().take());
        CAPTURE_PANICS.with(|c| c.set(true));
        TRACKING.with(|t| t.set(true));
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
        TRACKING.with(|t| t.set(false));
        CAPTURE_PANICS.with(|c| c.set(false));
        let (peak, biggest) = (
            PEAK.with(Cell::get).max(0) as usize,
            BIGGEST.with(Cell::get),
        );
        self.peak_ratio = self.peak_ratio.max(peak as f64 / limit as f64);
        match result {
            Ok(Ok(())) => {}
            Ok(Err(())) => self.errors += 1,
            Err(_) => {
                let msg = PANIC_MESSAGE
                    .with(|m| m.borrow_mut().take())
                    .unwrap_or_else(|| "panic".into());
                self.finding(case, msg, input, ext);
            }
        }
        if biggest > limit || peak > limit {
            let kind = format!(
                "allocates {} bytes at once, {peak} live, for a {}-byte input (bound {limit})",
                biggest,
                input.len()
            );
            // One entry per order of magnitude, not per size.
            let key = format!(
                "allocation over the bound (~2^{})",
                usize::BITS - peak.leading_zeros()
            );
            let entry = self
                .findings
                .entry(key)
                .or_insert((0, case, PathBuf::new()));
            entry.0 += 1;
            if entry.2.as_os_str().is_empty() {
                entry.2 = save_finding(self.target, case, input, ext);
                eprintln!("fuzz_readers: {} case {case}: {kind}", self.target);
            }
        }
    }

    fn finding(&mut self, case: u64, msg: String, input: &[u8], ext: &str) {
        // Group by the panic location and the message's first words.
        let key: String = msg.chars().take(160).collect();
        let entry = self
            .findings
            .entry(key)
            .or_insert((0, case, PathBuf::new()));
        entry.0 += 1;
        if entry.2.as_os_str().is_empty() {
            entry.2 = save_finding(self.target, case, input, ext);
            eprintln!("fuzz_readers: {} case {case}: {msg}", self.target);
        }
    }

    /// Prints the run's figures; Err lists the findings.
    fn finish(self) -> Result<(), String> {
        eprintln!(
            "fuzz_readers: {}: {} cases ({} errors, {} accepted) in {:.1} s, peak allocation {:.0} % of the bound, {} distinct findings (seed {})",
            self.target,
            self.cases,
            self.errors,
            self.cases - self.errors - self.findings.values().map(|f| f.0).sum::<u64>(),
            self.started.elapsed().as_secs_f64(),
            100.0 * self.peak_ratio,
            self.findings.len(),
            base_seed()
        );
        if !self.findings.is_empty() {
            let list: Vec<String> = self
                .findings
                .iter()
                .map(|(k, (n, case, file))| {
                    format!("  {n} × {k} (first: case {case}, input {})", file.display())
                })
                .collect();
            return Err(format!(
                "{}: {} kinds of finding (LGDM_FUZZ_SEED={}):\n{}",
                self.target,
                self.findings.len(),
                base_seed(),
                list.join("\n")
            ));
        }
        Ok(())
    }
}

fn save_finding(target: &str, case: u64, input: &[u8], ext: &str) -> PathBuf {
    let dir = std::env::temp_dir().join("lgdm-fuzz-findings");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(format!("{target}-seed{}-case{case}.{ext}", base_seed()));
    let _ = std::fs::write(&path, input);
    path
}

/// Marks an `Ok` result that breaks the reader's contract.
fn invalid(what: String) -> ! {
    panic!("invalid: {what}")
}

// ---------------------------------------------------------------------------------------------
// Mutations.

const INTERESTING_U64: [u64; 16] = [
    0,
    1,
    2,
    0x7f,
    0x80,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0x1_0000_0000,
    0x7fff_ffff_ffff_ffff,
    u64::MAX,
    1 << 40,
    100_000_000,
];

const INTERESTING_TEXT: [&str; 22] = [
    "0",
    "-1",
    "1",
    "3",
    "255",
    "65536",
    "2147483647",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "1e308",
    "1e999",
    "-1e999",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "0.0000001",
    "-0",
    "",
];

/// Byte-level mutations, 1 to 4 stacked.
fn mutate_bytes(rng: &mut ChaCha8Rng, input: &[u8]) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..rng.random_range(1..=4) {
        let len = b.len();
        match rng.random_range(0..9) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                b[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                b[i] = [0u8, 1, 0x7f, 0x80, 0xff, b'0', b'9', b'\n', b' ', b'-']
                    [rng.random_range(0..10)];
            }
            2 if len > 0 => {
                // An interesting integer, 2, 4 or 8 bytes, either endianness.
                let v = INTERESTING_U64[rng.random_range(0..INTERESTING_U64.len())];
                let width = [2usize, 4, 8][rng.random_range(0..3)];
                let (le, be) = (v.to_le_bytes(), v.to_be_bytes());
                let bytes = if rng.random_range(0..2) == 0 {
                    &le[..width]
                } else {
                    &be[8 - width..]
                };
                let i = rng.random_range(0..len);
                for (k, &x) in bytes.iter().enumerate() {
                    if let Some(slot) = b.get_mut(i + k) {
                        *slot = x;
                    }
                }
            }
            3 if len > 0 => {
                let i = rng.random_range(0..len);
                let n = rng.random_range(1..=(len - i).min(64));
                b.drain(i..i + n);
            }
            4 if len > 0 => {
                let i = rng.random_range(0..len);
                let n = rng.random_range(1..=(len - i).min(256));
                let piece = b[i..i + n].to_vec();
                let at = rng.random_range(0..=len);
                b.splice(at..at, piece);
            }
            5 => {
                let at = rng.random_range(0..=len);
                let n = rng.random_range(1..32);
                let piece: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                b.splice(at..at, piece);
            }
            6 if len > 0 => b.truncate(rng.random_range(0..len)),
            7 if len > 1 => {
                // Swap two ranges' first bytes (moves headers around).
                let (i, j) = (rng.random_range(0..len), rng.random_range(0..len));
                b.swap(i, j);
            }
            _ => {
                if len > 0 {
                    let i = rng.random_range(0..len);
                    b[i] = b[i].wrapping_add(rng.random_range(1..4));
                }
            }
        }
    }
    b
}

/// Text-level mutations (numbers replaced by huge or odd ones, lines cut, repeated, swapped,
/// tokens inserted), mixed with byte-level ones.
fn mutate_text(rng: &mut ChaCha8Rng, input: &[u8], keywords: &[&str]) -> Vec<u8> {
    if rng.random_range(0..4) == 0 {
        return mutate_bytes(rng, input);
    }
    let text = String::from_utf8_lossy(input).into_owned();
    let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
    for _ in 0..rng.random_range(1..=3) {
        if lines.is_empty() {
            lines.push(String::new());
        }
        let l = rng.random_range(0..lines.len());
        match rng.random_range(0..7) {
            0..=2 => {
                // Replace one number-like token.
                let mut tokens: Vec<String> = lines[l].split(' ').map(str::to_string).collect();
                let numeric: Vec<usize> = (0..tokens.len())
                    .filter(|&i| {
                        tokens[i]
                            .trim_matches(|c: char| {
                                matches!(c, ',' | ':' | '"' | '[' | ']' | '{' | '}')
                            })
                            .parse::<f64>()
                            .is_ok()
                    })
                    .collect();
                let i = if numeric.is_empty() {
                    rng.random_range(0..tokens.len())
                } else {
                    numeric[rng.random_range(0..numeric.len())]
                };
                let new = INTERESTING_TEXT[rng.random_range(0..INTERESTING_TEXT.len())];
                let old = tokens[i].clone();
                let core = old
                    .trim_matches(|c: char| matches!(c, ',' | ':' | '"' | '[' | ']' | '{' | '}'));
                tokens[i] = if core.is_empty() {
                    new.to_string()
                } else {
                    old.replacen(core, new, 1)
                };
                lines[l] = tokens.join(" ");
            }
            3 => {
                lines.remove(l);
            }
            4 => {
                let copy = lines[l].clone();
                let n = rng.random_range(1..4);
                for _ in 0..n {
                    lines.insert(l, copy.clone());
                }
            }
            5 => {
                let m = rng.random_range(0..lines.len());
                lines.swap(l, m);
            }
            _ => {
                let kw = keywords[rng.random_range(0..keywords.len())];
                let n = INTERESTING_TEXT[rng.random_range(0..INTERESTING_TEXT.len())];
                lines.insert(l, format!("{kw} {n} {n} {n}"));
            }
        }
    }
    lines.join("\n").into_bytes()
}

/// A JSON document with 1 to 3 values replaced (huge and odd numbers, other types), keys
/// removed or array elements repeated; the structure stays valid JSON, so the checks after
/// parsing are reached.
fn mutate_json(rng: &mut ChaCha8Rng, text: &[u8]) -> Vec<u8> {
    let Ok(mut doc) = serde_json::from_slice::<serde_json::Value>(text) else {
        return mutate_bytes(rng, text);
    };
    for _ in 0..rng.random_range(1..=3) {
        // Walk down to a random value (as a JSON pointer, then borrowed mutably).
        let mut pointer = String::new();
        let mut at = &doc;
        for _ in 0..rng.random_range(0..6) {
            match at {
                serde_json::Value::Object(m) if !m.is_empty() => {
                    let (k, next) = m.iter().nth(rng.random_range(0..m.len())).unwrap();
                    pointer += &format!("/{}", k.replace('~', "~0").replace('/', "~1"));
                    at = next;
                }
                serde_json::Value::Array(a) if !a.is_empty() => {
                    let k = rng.random_range(0..a.len());
                    pointer += &format!("/{k}");
                    at = &a[k];
                }
                _ => break,
            }
        }
        let v = doc.pointer_mut(&pointer).unwrap();
        match (rng.random_range(0..8), &mut *v) {
            (0, serde_json::Value::Object(m)) if !m.is_empty() => {
                let k = m.keys().nth(rng.random_range(0..m.len())).cloned().unwrap();
                m.remove(&k);
            }
            (0, serde_json::Value::Array(a)) if !a.is_empty() => {
                let k = rng.random_range(0..a.len());
                let copy = a[k].clone();
                let n = rng.random_range(1..4);
                for _ in 0..n {
                    a.push(copy.clone());
                }
            }
            (1, _) => *v = serde_json::Value::Null,
            (2, _) => *v = serde_json::json!(-1),
            (3, _) => *v = serde_json::json!("x"),
            (4, _) => *v = serde_json::json!(rng.random_range(0..5u64)),
            (5, _) => *v = serde_json::json!(1.0e300),
            _ => {
                *v = serde_json::json!(INTERESTING_U64[rng.random_range(0..INTERESTING_U64.len())])
            }
        }
    }
    serde_json::to_vec_pretty(&doc).unwrap()
}

fn random_bytes(rng: &mut ChaCha8Rng, max: usize) -> Vec<u8> {
    let n = rng.random_range(0..=max);
    (0..n).map(|_| rng.random()).collect()
}

/// Mutated (mostly) or random input from `seeds`.
fn input_from(rng: &mut ChaCha8Rng, seeds: &[Vec<u8>], text: Option<&[&str]>) -> Vec<u8> {
    let seed = &seeds[rng.random_range(0..seeds.len())];
    match rng.random_range(0..20) {
        0 => random_bytes(rng, 2048),
        1 => {
            // A prefix of a valid file followed by garbage.
            let cut = rng.random_range(0..=seed.len());
            let mut b = seed[..cut].to_vec();
            b.extend(random_bytes(rng, 256));
            b
        }
        _ => match text {
            Some(keywords) => mutate_text(rng, seed, keywords),
            None => mutate_bytes(rng, seed),
        },
    }
}

// ---------------------------------------------------------------------------------------------
// .npz

/// A stored zip of raw entries (like `npz::write_npz`, but of any bytes).
fn stored_zip(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, body) in entries {
        let crc = crc32fast::hash(body);
        let offset = out.len() as u32;
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        for v in [20u16, 0, 0, 0, 33] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&(name.len() as u16).to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(body);
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        for v in [20u16, 20, 0, 0, 0, 33] {
            central.extend_from_slice(&v.to_le_bytes());
        }
        central.extend_from_slice(&crc.to_le_bytes());
        central.extend_from_slice(&(body.len() as u32).to_le_bytes());
        central.extend_from_slice(&(body.len() as u32).to_le_bytes());
        central.extend_from_slice(&(name.len() as u16).to_le_bytes());
        for _ in 0..4 {
            central.extend_from_slice(&0u16.to_le_bytes());
        }
        central.extend_from_slice(&0u32.to_le_bytes());
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    let cd_offset = out.len() as u32;
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    let n = entries.len() as u16;
    for v in [0u16, 0, n, n] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(central.len() as u32).to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out
}

/// An `.npy` body with a hand-written header (any descr and shape text).
fn npy_with_header(descr: &str, shape: &str, version: u8, data: &[u8]) -> Vec<u8> {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    header.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.push(version);
    out.push(0);
    if version == 1 {
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

fn random_table(rng: &mut ChaCha8Rng) -> FeatureTable {
    let (n, dim) = (rng.random_range(0..6), rng.random_range(1..5));
    FeatureTable {
        dim,
        features: (0..n * dim).map(|_| rng.random_range(-1.0..1.0)).collect(),
        collection: (0..n).map(|_| rng.random_range(0..3)).collect(),
        category: (0..n).map(|_| rng.random_range(0..3)).collect(),
        instance: (0..n).map(|_| rng.random_range(0..3)).collect(),
        sequence: (0..n).map(|_| rng.random_range(0..9)).collect(),
        frame: (0..n).map(|_| rng.random_range(0..3)).collect(),
    }
}

fn npz_seeds(dir: &Path) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let path = dir.join("seed.npz");
    let mut zips = Vec::new();
    for _ in 0..4 {
        random_table(&mut rng).write_npz(&path).unwrap();
        zips.push(std::fs::read(&path).unwrap());
    }
    let (f, u, w) = (
        [1.5f32, -2.0, 3.25, 0.0, 1e-3, 7.0],
        [1u32, 2, 3, 4],
        [5u64, 6],
    );
    write_npz(
        &path,
        &[
            ("a", NpyRef::F32(&f, &[2, 3])),
            ("b", NpyRef::U32(&u, &[4])),
            ("c", NpyRef::U64(&w, &[1, 2, 1])),
            ("empty", NpyRef::F32(&[], &[0, 5])),
        ],
    )
    .unwrap();
    zips.push(std::fs::read(&path).unwrap());
    // Bodies: what numpy writes (versions 1 and 2, every dtype the reader knows).
    let mut bodies = vec![
        npy_bytes(NpyRef::F32(&f, &[3, 2])),
        npy_bytes(NpyRef::U64(&w, &[2])),
        npy_with_header("<i4", "(2,)", 1, &[1, 0, 0, 0, 255, 255, 255, 255]),
        npy_with_header("<i8", "(1, 1)", 2, &[9, 0, 0, 0, 0, 0, 0, 0]),
        npy_with_header("<f8", "(1,)", 3, &1.5f64.to_le_bytes()),
        npy_with_header("<f4", "()", 1, &2.0f32.to_le_bytes()),
    ];
    // Huge shapes whose product overflows or exceeds the data.
    for shape in [
        "(4294967296, 4294967296)",
        "(18446744073709551615,)",
        "(18446744073709551615, 2)",
        "(3037000500, 3037000500)",
        "(1000000000000,)",
        "(2, 0, 18446744073709551615)",
    ] {
        bodies.push(npy_with_header("<f4", shape, 1, &[0; 16]));
    }
    for body in bodies.clone() {
        zips.push(stored_zip(&[("features.npy", &body)]));
    }
    (zips, bodies)
}

/// Sets a little-endian field of a zip record (sizes, counts, offsets) to a huge value.
fn huge_zip_field(rng: &mut ChaCha8Rng, zip: &mut [u8]) {
    let find = |sig: u32| -> Vec<usize> {
        (0..zip.len().saturating_sub(3))
            .filter(|&i| u32::from_le_bytes(zip[i..i + 4].try_into().unwrap()) == sig)
            .collect()
    };
    // (signature, field offset, width)
    let fields: [(u32, usize, usize); 9] = [
        (0x0605_4b50, 8, 2),  // entries on disk
        (0x0605_4b50, 10, 2), // entries
        (0x0605_4b50, 16, 4), // central directory offset
        (0x0201_4b50, 20, 4), // compressed size
        (0x0201_4b50, 28, 2), // name length
        (0x0201_4b50, 30, 2), // extra length
        (0x0201_4b50, 42, 4), // local header offset
        (0x0403_4b50, 26, 2), // local name length
        (0x0403_4b50, 28, 2), // local extra length
    ];
    let (sig, off, width) = fields[rng.random_range(0..fields.len())];
    let at = find(sig);
    if at.is_empty() {
        return;
    }
    let p = at[rng.random_range(0..at.len())] + off;
    let v = INTERESTING_U64[rng.random_range(0..INTERESTING_U64.len())].to_le_bytes();
    for (k, &byte) in v.iter().take(width).enumerate() {
        if let Some(b) = zip.get_mut(p + k) {
            *b = byte;
        }
    }
}

fn check_arrays(arrays: &[lgdm_pointcloud::npz::NpyArray]) {
    for a in arrays {
        let count = a
            .shape
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d));
        if count != Some(a.data.len()) {
            invalid(format!(
                "array `{}` has shape {:?} but {} values",
                a.name,
                a.shape,
                a.data.len()
            ));
        }
    }
}

fn fuzz_npz() -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let (zips, bodies) = npz_seeds(dir.path());
    let path = dir.path().join("case.npz");
    let bound = Bound {
        fixed: 1 << 20,
        per_byte: 8,
    };
    let mut fuzz = Fuzz::new("npz");
    for case in 0..cases() {
        let mut rng = case_rng("npz", case);
        let bytes = match rng.random_range(0..4) {
            0 => {
                // A mutated .npy body in a valid zip (so the CRC passes).
                let seed = &bodies[rng.random_range(0..bodies.len())];
                let body = mutate_bytes(&mut rng, seed);
                let name = ["features.npy", "frame.npy", "x"][rng.random_range(0..3)];
                stored_zip(&[(name, &body)])
            }
            1 => {
                let mut z = zips[rng.random_range(0..zips.len())].clone();
                huge_zip_field(&mut rng, &mut z);
                z
            }
            _ => input_from(&mut rng, &zips, None),
        };
        std::fs::write(&path, &bytes).unwrap();
        fuzz.case(case, &bytes, "npz", bound.of(bytes.len()), || {
            let a = read_npz(&path);
            if let Ok(arrays) = &a {
                check_arrays(arrays);
            }
            for exact in [false, true] {
                let t = if exact {
                    FeatureTable::read_npz_exact(&path)
                } else {
                    FeatureTable::read_npz(&path)
                };
                if let Ok(t) = t
                    && let Err(e) = t.check()
                {
                    invalid(format!("table: {e}"));
                }
            }
            a.map(|_| ()).map_err(|_| ())
        });
    }
    fuzz.finish()
}

fn fuzz_npy() -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let (_, bodies) = npz_seeds(dir.path());
    let bound = Bound {
        fixed: 64 << 10,
        per_byte: 4,
    };
    let mut fuzz = Fuzz::new("npy");
    for case in 0..cases() * 4 {
        let mut rng = case_rng("npy", case);
        let body = input_from(&mut rng, &bodies, Some(&["'shape':", "'descr':", "(", ","]));
        fuzz.case(
            case,
            &body,
            "npy",
            bound.of(body.len()),
            || match parse_npy(&body) {
                Ok((shape, data)) => {
                    let count = shape.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
                    if count != Some(data.len()) {
                        invalid(format!("shape {shape:?} but {} values", data.len()));
                    }
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    fuzz.finish()
}

// ---------------------------------------------------------------------------------------------
// Datasets: manifest.json and MCAP collection files.

struct DatasetFixture {
    _dir: tempfile::TempDir,
    manifest_text: String,
    /// Collection files (relative path, bytes) in the generated flavour.
    files: Vec<(String, Vec<u8>)>,
    /// The same collections rewritten without CRCs: (flavour, relative path, bytes).
    variants: Vec<(String, Vec<u8>)>,
}

/// A small generated dataset (2 categories × 1 instance, 2 collections, 2 frames, few
/// points) and variants of its collection files written without CRCs (zstd chunks,
/// uncompressed chunks, no chunks), so mutations reach the record and message parsers.
fn dataset_fixture() -> &'static DatasetFixture {
    static FIXTURE: OnceLock<DatasetFixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("ds");
        let mut spec = DatasetSpec::small(3);
        spec.categories = vec!["mug".into(), "bowl".into()];
        spec.instances_per_category = 1;
        spec.collections = standard_collections().into_iter().take(2).collect();
        spec.frames_per_sequence = 2;
        spec.max_points_per_view = 64;
        spec.grasp_images = 0;
        spec.previews = false;
        let manifest = generate(&spec, &root, &mut |_| {}).unwrap();
        let ds = Dataset::open(&root).unwrap();
        let mut files = Vec::new();
        let mut variants = Vec::new();
        for c in &manifest.collections {
            files.push((c.file.clone(), std::fs::read(root.join(&c.file)).unwrap()));
            let seqs: Vec<_> = ds.sequences(c.index).unwrap().map(Result::unwrap).collect();
            for flavour in 0..3 {
                variants.push((
                    c.file.clone(),
                    write_collection(&manifest, c.index, &seqs, flavour),
                ));
            }
        }
        DatasetFixture {
            manifest_text: std::fs::read_to_string(root.join(MANIFEST_FILE)).unwrap(),
            _dir: dir,
            files,
            variants,
        }
    })
}

/// A collection file like the generator's, without CRCs: zstd chunks (0), uncompressed chunks
/// (1) or no chunks (2).
fn write_collection(
    manifest: &Manifest,
    collection: u32,
    seqs: &[lgdm_pointcloud::dataset::Sequence],
    flavour: u8,
) -> Vec<u8> {
    let mut cursor = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new()
            .compression(if flavour == 0 {
                Some(mcap::Compression::Zstd)
            } else {
                None
            })
            .use_chunks(flavour != 2)
            .calculate_chunk_crcs(false)
            .calculate_data_section_crc(false)
            .calculate_summary_section_crc(false)
            .create(&mut cursor)
            .unwrap();
        let (name, encoding, data) = point_cloud_schema();
        let schema = w.add_schema(&name, &encoding, &data).unwrap();
        for seq in seqs {
            let inst = &manifest.instances[seq.instance as usize];
            let meta = BTreeMap::from([
                ("collection".to_string(), collection.to_string()),
                ("category".to_string(), seq.category.to_string()),
                (
                    "category_name".to_string(),
                    manifest.categories[seq.category as usize].clone(),
                ),
                ("instance".to_string(), seq.instance.to_string()),
                ("instance_name".to_string(), inst.name.clone()),
                ("frames".to_string(), seq.frames.len().to_string()),
            ]);
            let ch = w
                .add_channel(schema, &format!("/{}", inst.name), "protobuf", &meta)
                .unwrap();
            for (f, cloud) in seq.frames.iter().enumerate() {
                let t = f as u64 * 400_000_000;
                w.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: ch,
                        sequence: f as u32,
                        log_time: t,
                        publish_time: t,
                    },
                    &encode_point_cloud(cloud, t),
                )
                .unwrap();
            }
        }
        w.finish().unwrap();
    }
    cursor.into_inner()
}

/// A case directory: `manifest.json` (rewritten per case) and the collection files.
fn case_dir(parent: &Path, fixture: &DatasetFixture) -> PathBuf {
    let dir = parent.join("case");
    std::fs::create_dir_all(dir.join("collections")).unwrap();
    for (file, bytes) in &fixture.files {
        std::fs::write(dir.join(file), bytes).unwrap();
    }
    dir
}

/// Reads everything a dataset directory offers; Err(()) at the first error.
fn read_dataset(dir: &Path) -> Result<(), ()> {
    let ds = Dataset::open(dir).map_err(|_| ())?;
    let m = ds.manifest();
    let mut result = Ok(());
    for c in 0..m.collections.len() as u32 {
        for seq in ds.sequences(c).map_err(|_| ())? {
            let Ok(seq) = seq else {
                result = Err(());
                break;
            };
            if seq.frames.len() != m.frames_per_sequence {
                invalid(format!(
                    "{} frames, manifest {}",
                    seq.frames.len(),
                    m.frames_per_sequence
                ));
            }
            if m.instances.get(seq.instance as usize).map(|i| i.category) != Some(seq.category) {
                invalid(format!(
                    "instance {} category {}",
                    seq.instance, seq.category
                ));
            }
            for cloud in &seq.frames {
                check_cloud(cloud);
            }
        }
    }
    // The cache's table check against whatever the manifest says.
    let table = FeatureTable::new(675);
    let _ = table.check_dataset(m, Some(675));
    result
}

fn check_cloud(cloud: &PointCloud) {
    if !cloud.points.iter().flatten().all(|v| v.is_finite()) {
        invalid("a non-finite point".into());
    }
    if let Some(c) = &cloud.colors
        && c.len() != cloud.points.len()
    {
        invalid(format!(
            "{} colours for {} points",
            c.len(),
            cloud.points.len()
        ));
    }
}

fn with_bytes(manifest: &str, file: &str, bytes: usize) -> String {
    let mut m: serde_json::Value = serde_json::from_str(manifest).unwrap();
    for c in m["collections"].as_array_mut().unwrap() {
        if c["file"] == file {
            c["bytes"] = serde_json::json!(bytes);
        }
    }
    serde_json::to_string_pretty(&m).unwrap()
}

fn fuzz_collections() -> Result<(), String> {
    let fixture = dataset_fixture();
    let tmp = tempfile::tempdir().unwrap();
    let dir = case_dir(tmp.path(), fixture);
    let mut fuzz = Fuzz::new("mcap");
    let bound = Bound {
        fixed: 8 << 20,
        per_byte: 64,
    };
    let all: Vec<&(String, Vec<u8>)> = fixture.files.iter().chain(&fixture.variants).collect();
    let mut last_manifest = String::new();
    let manifest_len = fixture.manifest_text.len();
    let other_files = fixture.files.iter().map(|f| f.1.len()).max().unwrap_or(0);
    for case in 0..cases() {
        let mut rng = case_rng("mcap", case);
        let (file, seed) = all[rng.random_range(0..all.len())];
        let bytes = input_from(&mut rng, std::slice::from_ref(seed), None);
        std::fs::write(dir.join(file), &bytes).unwrap();
        // Mostly with the manifest's size updated, so the reader gets to the bytes.
        let manifest = if rng.random_range(0..8) == 0 {
            fixture.manifest_text.clone()
        } else {
            with_bytes(&fixture.manifest_text, file, bytes.len())
        };
        if manifest != last_manifest {
            std::fs::write(dir.join(MANIFEST_FILE), &manifest).unwrap();
            last_manifest = manifest;
        }
        // The reader also reads the manifest and the other collection.
        let len = bytes.len() + manifest_len + other_files;
        fuzz.case(case, &bytes, "mcap", bound.of(len), || read_dataset(&dir));
        std::fs::write(
            dir.join(file),
            &fixture.files.iter().find(|f| &f.0 == file).unwrap().1,
        )
        .unwrap();
    }
    fuzz.finish()
}

fn fuzz_point_cloud_messages() -> Result<(), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let seeds: Vec<Vec<u8>> = (0..4)
        .map(|k| {
            let n = rng.random_range(0..20);
            let points = (0..n)
                .map(|_| [rng.random(), rng.random(), rng.random()])
                .collect();
            let colors = (k % 2 == 0).then(|| (0..n).map(|_| [1, 2, 3]).collect());
            encode_point_cloud(&PointCloud::new(points, colors), 12_345)
        })
        .collect();
    let bound = Bound {
        fixed: 64 << 10,
        per_byte: 4,
    };
    let mut fuzz = Fuzz::new("pointcloud");
    for case in 0..cases() * 4 {
        let mut rng = case_rng("pointcloud", case);
        let bytes = input_from(&mut rng, &seeds, None);
        fuzz.case(
            case,
            &bytes,
            "pb",
            bound.of(bytes.len()),
            || match decode_point_cloud(&bytes) {
                Ok(cloud) => {
                    check_cloud(&cloud);
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    fuzz.finish()
}

fn fuzz_manifests() -> Result<(), String> {
    let fixture = dataset_fixture();
    let tmp = tempfile::tempdir().unwrap();
    let dir = case_dir(tmp.path(), fixture);
    let seeds = vec![fixture.manifest_text.clone().into_bytes()];
    let collection_bytes: usize = fixture.files.iter().map(|f| f.1.len()).sum();
    let bound = Bound {
        fixed: 8 << 20,
        per_byte: 64,
    };
    let mut fuzz = Fuzz::new("manifest");
    let keywords = [
        "\"frames_per_sequence\":",
        "\"views\":",
        "\"bytes\":",
        "\"sequences\":",
        "\"category\":",
        "\"index\":",
    ];
    for case in 0..cases() {
        let mut rng = case_rng("manifest", case);
        let bytes = if rng.random_range(0..2) == 0 {
            mutate_json(&mut rng, &seeds[0])
        } else {
            input_from(&mut rng, &seeds, Some(&keywords))
        };
        std::fs::write(dir.join(MANIFEST_FILE), &bytes).unwrap();
        // The reader also reads the collection files the manifest names (each possibly many
        // times: the bound grows with the manifest's length too).
        let limit = bound.of(bytes.len() + collection_bytes);
        fuzz.case(case, &bytes, "json", limit, || read_dataset(&dir));
    }
    let mut result = fuzz.finish();
    // Huge numbers where the reader used to trust them.
    let m: serde_json::Value = serde_json::from_str(&fixture.manifest_text).unwrap();
    for (field, value) in [
        ("frames_per_sequence", serde_json::json!(u64::MAX)),
        ("frames_per_sequence", serde_json::json!(1u64 << 40)),
        ("views", serde_json::json!(u64::MAX)),
    ] {
        let mut m = m.clone();
        m[field] = value.clone();
        std::fs::write(dir.join(MANIFEST_FILE), serde_json::to_string(&m).unwrap()).unwrap();
        if Dataset::open(&dir).is_ok() {
            let failure = format!("manifest: `{field}` = {value} accepted");
            result = Err(result
                .err()
                .map_or(failure.clone(), |r| format!("{r}\n{failure}")));
        }
    }
    result
}

// ---------------------------------------------------------------------------------------------
// Meshes.

/// A tetrahedron in every format the importer reads: (extension, bytes).
fn mesh_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let v = [
        [0.0f32, 0.0, 0.0],
        [0.1, 0.0, 0.0],
        [0.0, 0.1, 0.0],
        [0.0, 0.0, 0.1],
    ];
    let f = [[0u32, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let mut out = Vec::new();
    let mut obj = String::from("# tetrahedron\nmtllib m.mtl\no tet\nusemtl red\n");
    for p in v {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    obj += "vn 0 0 1\nvt 0.5 0.5\n";
    for t in f {
        obj += &format!("f {}/1/1 {}/1/1 {}/1/1\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    obj += "f 1 2 3 4\nf -1 -2 -3\n";
    out.push(("obj", obj.into_bytes()));
    let mut stl = String::from("solid tet\n");
    for t in f {
        stl += " facet normal 0 0 0\n  outer loop\n";
        for i in t {
            let p = v[i as usize];
            stl += &format!("   vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        stl += "  endloop\n endfacet\n";
    }
    stl += "endsolid tet\n";
    out.push(("stl", stl.into_bytes()));
    let mut bin = vec![0u8; 80];
    bin.extend_from_slice(&(f.len() as u32).to_le_bytes());
    for t in f {
        bin.extend_from_slice(&[0u8; 12]);
        for i in t {
            for c in v[i as usize] {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        bin.extend_from_slice(&[0, 0]);
    }
    out.push(("stl", bin));
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\ncomment tet\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
             element face 4\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let mut ascii = header("ascii");
    for p in v {
        ascii += &format!("{} {} {} 200 100 50\n", p[0], p[1], p[2]);
    }
    for t in f {
        ascii += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    out.push(("ply", ascii.into_bytes()));
    for big in [false, true] {
        let mut b = header(if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        })
        .into_bytes();
        for p in v {
            for c in p {
                b.extend_from_slice(&if big {
                    c.to_be_bytes()
                } else {
                    c.to_le_bytes()
                });
            }
            b.extend_from_slice(&[200, 100, 50]);
        }
        for t in f {
            b.push(3);
            for i in t {
                let i = i as i32;
                b.extend_from_slice(&if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
        }
        out.push(("ply", b));
    }
    out
}

/// Huge counts where the formats declare them.
fn huge_mesh_counts(rng: &mut ChaCha8Rng, ext: &str, bytes: &[u8]) -> Vec<u8> {
    let big = INTERESTING_TEXT[rng.random_range(5..12)];
    match ext {
        "ply" => {
            let text = String::from_utf8_lossy(bytes).into_owned();
            let el = ["element vertex 4", "element face 4"][rng.random_range(0..2)];
            let Some(at) = text.find(el) else {
                return bytes.to_vec();
            };
            let head_len = at + el.len();
            let mut out = bytes[..head_len - 1].to_vec();
            out.extend_from_slice(big.as_bytes());
            out.extend_from_slice(&bytes[head_len..]);
            out
        }
        "stl" if bytes.len() >= 84 && !bytes.starts_with(b"solid") => {
            let mut out = bytes.to_vec();
            let v = INTERESTING_U64[rng.random_range(0..INTERESTING_U64.len())] as u32;
            out[80..84].copy_from_slice(&v.to_le_bytes());
            out
        }
        _ => {
            let mut out = bytes.to_vec();
            out.extend_from_slice(format!("f 1 2 {big}\nv {big} 0 0\nf -{big} 1 2\n").as_bytes());
            out
        }
    }
}

fn check_mesh(mesh: &lgdm_pointcloud::mesh::Mesh) {
    let n = mesh.vertices.len();
    if mesh.triangles.is_empty() || mesh.colors.len() != mesh.triangles.len() {
        invalid(format!(
            "{} triangles, {} colours",
            mesh.triangles.len(),
            mesh.colors.len()
        ));
    }
    if !mesh.vertices.iter().flatten().all(|v| v.is_finite()) {
        invalid("a non-finite vertex".into());
    }
    if mesh.triangles.iter().flatten().any(|&i| i as usize >= n) {
        invalid(format!("an index beyond the {n} vertices"));
    }
}

fn fuzz_meshes() -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    let seeds = mesh_seeds();
    let keywords = [
        "v",
        "f",
        "vt",
        "vn",
        "o",
        "g",
        "usemtl",
        "mtllib",
        "element vertex",
        "element face",
        "property float",
        "property list uchar int",
        "facet normal",
        "vertex",
        "endloop",
    ];
    // ply-rs preallocates up to 65,536 elements per element kind whatever the header says
    // (a constant ~4.7 MiB each, not tied to the input).
    let bound = Bound {
        fixed: 16 << 20,
        per_byte: 256,
    };
    let mut fuzz = Fuzz::new("mesh");
    for case in 0..cases() * 4 {
        let mut rng = case_rng("mesh", case);
        let (ext, seed) = &seeds[rng.random_range(0..seeds.len())];
        let text = ext == &"obj" || !seed.contains(&0);
        let bytes = match rng.random_range(0..6) {
            0 => huge_mesh_counts(&mut rng, ext, seed),
            _ => input_from(
                &mut rng,
                std::slice::from_ref(seed),
                text.then_some(&keywords[..]),
            ),
        };
        let path = dir.path().join(format!("case.{ext}"));
        std::fs::write(&path, &bytes).unwrap();
        fuzz.case(
            case,
            &bytes,
            ext,
            bound.of(bytes.len()),
            || match load_mesh(&path) {
                Ok((mesh, _)) => {
                    check_mesh(&mesh);
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    fuzz.finish()
}

fn obj_material_libraries() -> Result<(), String> {
    // `mtllib /dev/zero` was read without end (an abort asking for gigabytes); a directory or
    // device named there now leaves the default colour, like a missing file.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dev.obj");
    let obj = b"mtllib /dev/zero\nmtllib .\nusemtl red\nv 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n";
    std::fs::write(&path, obj).unwrap();
    let bound = Bound {
        fixed: 16 << 20,
        per_byte: 256,
    };
    let mut fuzz = Fuzz::new("mtllib");
    fuzz.case(0, obj, "obj", bound.of(obj.len()), || {
        match load_mesh(&path) {
            Ok((mesh, _)) => {
                check_mesh(&mesh);
                Ok(())
            }
            Err(_) => Err(()),
        }
    });
    fuzz.finish()?;
    match load_mesh(&path) {
        Ok((mesh, _)) if mesh.triangles.len() == 1 => Ok(()),
        other => Err(format!("mtllib: {:?}", other.map(|m| m.0.triangles.len()))),
    }
}

// ---------------------------------------------------------------------------------------------
// Cornell files.

fn fuzz_rectangles() -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pcd0100cpos.txt");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let seeds: Vec<Vec<u8>> = (0..3)
        .map(|k| {
            let rects: Vec<GraspRectangle> = (0..k * 2 + 1)
                .map(|_| GraspRectangle {
                    corners_px: [0; 4]
                        .map(|_| [rng.random_range(0.0..640.0), rng.random_range(0.0..480.0)]),
                })
                .collect();
            write_rectangles(&path, &rects).unwrap();
            std::fs::read(&path).unwrap()
        })
        .collect();
    let bound = Bound {
        fixed: 64 << 10,
        per_byte: 8,
    };
    let mut fuzz = Fuzz::new("rectangles");
    for case in 0..cases() * 2 {
        let mut rng = case_rng("rectangles", case);
        let bytes = input_from(&mut rng, &seeds, Some(&["", "1 2", "nan nan"]));
        std::fs::write(&path, &bytes).unwrap();
        fuzz.case(
            case,
            &bytes,
            "txt",
            bound.of(bytes.len()),
            || match read_rectangles(&path) {
                Ok(rects) => {
                    if !rects
                        .iter()
                        .flat_map(|r| r.corners_px)
                        .flatten()
                        .all(|v| v.is_finite())
                    {
                        invalid("a non-finite corner".into());
                    }
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    fuzz.finish()
}

/// PNG chunk `kind`'s data replaced, with its CRC recomputed (the decoder checks CRCs).
fn png_with_chunk(png: &[u8], kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut out = png[..8].to_vec();
    let mut p = 8;
    while p + 12 <= png.len() {
        let len = u32::from_be_bytes(png[p..p + 4].try_into().unwrap()) as usize;
        let end = (p + 12 + len).min(png.len());
        if &png[p + 4..p + 8] == kind {
            out.extend_from_slice(&(data.len() as u32).to_be_bytes());
            out.extend_from_slice(kind);
            out.extend_from_slice(data);
            let mut h = crc32fast::Hasher::new();
            h.update(kind);
            h.update(data);
            out.extend_from_slice(&h.finalize().to_be_bytes());
        } else {
            out.extend_from_slice(&png[p..end]);
        }
        p = end;
    }
    out
}

fn fuzz_images() -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let mut png_seeds = Vec::new();
    let mut tiff_seeds = Vec::new();
    for (w, h) in [(1usize, 1usize), (7, 3), (16, 16)] {
        let p = dir.path().join("seed.png");
        let img = RgbImage::from_pixels(w, h, (0..w * h).map(|i| [i as u8, 7, 200]).collect());
        img.write_png(&p).unwrap();
        png_seeds.push(std::fs::read(&p).unwrap());
        let t = dir.path().join("seed.tiff");
        let depth: Vec<f32> = (0..w * h).map(|i| i as f32 * 0.01).collect();
        write_depth_tiff(&t, w, h, &depth).unwrap();
        tiff_seeds.push(std::fs::read(&t).unwrap());
    }
    let bound = Bound {
        fixed: 1 << 20,
        per_byte: 1100,
    };
    let (png_path, tiff_path) = (dir.path().join("case.png"), dir.path().join("case.tiff"));
    let mut fuzz = Fuzz::new("png");
    for case in 0..cases() * 2 {
        let mut rng = case_rng("png", case);
        let bytes = if rng.random_range(0..4) == 0 {
            // A valid header declaring a huge image.
            let seed = &png_seeds[rng.random_range(0..png_seeds.len())];
            let mut ihdr = Vec::new();
            for _ in 0..2 {
                let v = [1u32, 0, 65_535, 1 << 20, 0x7fff_ffff, u32::MAX][rng.random_range(0..6)];
                ihdr.extend_from_slice(&v.to_be_bytes());
            }
            ihdr.extend_from_slice(&[
                [8u8, 16][rng.random_range(0..2)],
                [2u8, 6, 0, 3][rng.random_range(0..4)],
                0,
                0,
                rng.random_range(0..2),
            ]);
            png_with_chunk(seed, b"IHDR", &ihdr)
        } else {
            input_from(&mut rng, &png_seeds, None)
        };
        std::fs::write(&png_path, &bytes).unwrap();
        fuzz.case(
            case,
            &bytes,
            "png",
            bound.of(bytes.len()),
            || match RgbImage::read_png(&png_path) {
                Ok(img) => {
                    if img.data.len() != img.width * img.height {
                        invalid(format!(
                            "{}×{} image with {} pixels",
                            img.width,
                            img.height,
                            img.data.len()
                        ));
                    }
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    let png = fuzz.finish();
    let mut fuzz = Fuzz::new("tiff");
    for case in 0..cases() * 2 {
        let mut rng = case_rng("tiff", case);
        let bytes = input_from(&mut rng, &tiff_seeds, None);
        std::fs::write(&tiff_path, &bytes).unwrap();
        fuzz.case(
            case,
            &bytes,
            "tiff",
            bound.of(bytes.len()),
            || match read_depth_tiff(&tiff_path) {
                Ok((w, h, v)) => {
                    if v.len() != w * h {
                        invalid(format!("{w}×{h} depth with {} values", v.len()));
                    }
                    Ok(())
                }
                Err(_) => Err(()),
            },
        );
    }
    let tiff = fuzz.finish();
    png.and(tiff)
}

// ---------------------------------------------------------------------------------------------
// The tests: one per kind of file, each failing with every finding of its readers.

fn all(families: &[fn() -> Result<(), String>]) {
    let failures: Vec<String> = families.iter().filter_map(|f| f().err()).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn npz_files_never_panic_nor_over_allocate() {
    all(&[fuzz_npz, fuzz_npy]);
}

#[test]
fn collection_files_never_panic_nor_over_allocate() {
    all(&[fuzz_collections, fuzz_point_cloud_messages]);
}

#[test]
fn manifests_never_panic_nor_over_allocate() {
    all(&[fuzz_manifests]);
}

#[test]
fn meshes_never_panic_nor_over_allocate() {
    all(&[obj_material_libraries, fuzz_meshes]);
}

#[test]
fn cornell_files_never_panic_nor_over_allocate() {
    all(&[fuzz_rectangles, fuzz_images]);
}
