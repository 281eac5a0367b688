//! Helpers shared by the end-to-end tests that drive the real `lgdm` binary (`e2e`, `e2e_ae`,
//! `sim_e2e`, `sim_pickplace_e2e`).
//! Each test binary includes this file with `#[path]` and uses what it needs.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `lgdm` binary under test, with its feature cache in `cache`.
pub fn lgdm(cache: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lgdm"));
    c.env("LGDM_CACHE_DIR", cache);
    c
}

/// A scratch directory for this test binary: `<cargo tmp>/<tag>-<pid>`, created.
pub fn work_dir(tag: &str) -> PathBuf {
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A tiny dataset generated at `dir` (small preset, 2 frames per sequence: 900 views, no grasp
/// images; seed 5), with the feature cache in `cache`.
pub fn tiny_dataset(dir: &Path, cache: &Path) {
    check(
        lgdm(cache)
            .args(["gen-dataset", "--preset", "small", "--frames", "2"])
            .args(["--grasp-images", "0", "--seed", "5", "--progress", "none"])
            .arg("--out")
            .arg(dir)
            .output()
            .unwrap(),
        "gen-dataset",
    );
}

/// Panics, showing both streams, unless the command succeeded.
pub fn check(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed ({}):\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// metrics.json without what differs between two runs of one experiment: the wall-clock fields
/// and the dataset path.
pub fn without_times(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| {
                    !matches!(
                        k.as_str(),
                        "seconds" | "train_seconds" | "inference_ms_per_sample" | "dataset"
                    )
                })
                .map(|(k, v)| (k.clone(), without_times(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(without_times).collect()),
        other => other.clone(),
    }
}

/// A run directory's results.json.
pub fn read_results(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A sim run's results.json without the wall-clock fields (every object named `wall`).
pub fn without_wall(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.iter()
                .filter(|(k, _)| k.as_str() != "wall")
                .map(|(k, v)| (k.clone(), without_wall(v)))
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(without_wall).collect()),
        other => other.clone(),
    }
}

/// The Wilson 95 % score interval of `successes` in `trials`, computed here independently of
/// the library: as the two roots of the quadratic whose solutions p satisfy
/// (p̂ − p)² = z² p (1 − p) / n, i.e. (1 + z²/n) p² − (2 p̂ + z²/n) p + p̂² = 0. (0, 1) for no
/// trials. Pinned to `tests/fixtures/wilson.json` (values of the Rust formula) by
/// `sim_e2e`'s `the_tests_wilson_interval_matches_the_fixture`.
pub fn wilson_interval(successes: u64, trials: u64) -> (f64, f64) {
    if trials == 0 {
        return (0.0, 1.0);
    }
    let z = 1.959_963_984_540_054_f64;
    let n = trials as f64;
    let p = successes as f64 / n;
    let k = z * z / n;
    let (a, b) = (1.0 + k, 2.0 * p + k);
    // The discriminant b² − 4(1 + k)p̂², written as k (4 p̂ (1 − p̂) + k) to avoid cancellation.
    let root = (k * (4.0 * p * (1.0 - p) + k)).sqrt();
    ((b - root) / (2.0 * a), (b + root) / (2.0 * a))
}

/// The entries of `tests/fixtures/wilson.json`: (successes, trials, low, high).
pub fn wilson_fixture() -> Vec<(u64, u64, f64, f64)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/wilson.json");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("the Wilson fixture {}: {e}", path.display()));
    let cases: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
    cases
        .iter()
        .map(|c| {
            (
                c["successes"].as_u64().unwrap(),
                c["trials"].as_u64().unwrap(),
                c["low"].as_f64().unwrap(),
                c["high"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// A rate of a results.json (`successes`, `trials`, `value`, `wilson_low`, `wilson_high`) is
/// right: successes ≤ trials, value = successes / trials (`null` without trials), and the
/// interval is the Wilson 95 % interval of the counts (to 1e-12, against [`wilson_interval`]),
/// exactly 0 at the low end without successes and exactly 1 at the high end without failures.
pub fn assert_rate(rate: &serde_json::Value, what: &str) {
    let trials = rate["trials"]
        .as_u64()
        .unwrap_or_else(|| panic!("{what}: no trials in {rate}"));
    let successes = rate["successes"]
        .as_u64()
        .unwrap_or_else(|| panic!("{what}: no successes in {rate}"));
    assert!(successes <= trials, "{what}: {rate}");
    let (lo, hi) = (
        rate["wilson_low"].as_f64().unwrap(),
        rate["wilson_high"].as_f64().unwrap(),
    );
    if trials == 0 {
        assert!(
            rate["value"].is_null(),
            "{what}: a value without trials: {rate}"
        );
    } else {
        let v = rate["value"].as_f64().unwrap();
        assert_eq!(v, successes as f64 / trials as f64, "{what}: {rate}");
    }
    let (want_lo, want_hi) = wilson_interval(successes, trials);
    assert!(
        (lo - want_lo).abs() < 1e-12 && (hi - want_hi).abs() < 1e-12,
        "{what}: Wilson interval ({lo}, {hi}) of {successes}/{trials}, expected \
         ({want_lo}, {want_hi})"
    );
    if successes == 0 {
        assert_eq!(lo, 0.0, "{what}: not exact at the low end: {rate}");
    }
    if successes == trials {
        assert_eq!(hi, 1.0, "{what}: not exact at the high end: {rate}");
    }
}

/// A rate's `successes`, `trials` and `value` (`value` 0 without trials).
pub fn rate_counts(rate: &serde_json::Value) -> (u64, u64, f64) {
    (
        rate["successes"].as_u64().unwrap(),
        rate["trials"].as_u64().unwrap(),
        rate["value"].as_f64().unwrap_or(0.0),
    )
}

/// A decoded PNG as 8-bit RGB.
#[derive(Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<[u8; 3]>,
}

/// Decodes a PNG (any colour type and depth) to 8-bit RGB (alpha dropped).
pub fn read_png(path: &Path) -> Image {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder
        .read_info()
        .unwrap_or_else(|e| panic!("{}: not a PNG: {e}", path.display()));
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader
        .next_frame(&mut buf)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let data = &buf[..info.buffer_size()];
    let rgb = match info.color_type {
        png::ColorType::Rgb => data.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
        png::ColorType::Rgba => data.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect(),
        png::ColorType::Grayscale => data.iter().map(|&g| [g, g, g]).collect(),
        png::ColorType::GrayscaleAlpha => data.chunks_exact(2).map(|p| [p[0]; 3]).collect(),
        other => panic!("{}: unexpected colour type {other:?}", path.display()),
    };
    Image {
        width: info.width,
        height: info.height,
        rgb,
    }
}

/// What a plot shows: its background colour (the commonest), how many pixels differ from it,
/// and its saturated colours (max − min channel ≥ 48: data series and bars, not the grey and
/// black of axes and text) that cover at least 20 pixels each, commonest first.
#[derive(Debug)]
pub struct PlotContent {
    pub width: u32,
    pub height: u32,
    pub background: [u8; 3],
    pub non_background: usize,
    pub colours: Vec<([u8; 3], usize)>,
}

/// Decodes a plot and checks that it is a drawn chart, not an empty canvas: at least 640 × 400
/// pixels on a near-white background covering 30 % of it or more, at least 2 % of the pixels drawn
/// (axes, labels, data), and at least `min_colours` distinct saturated colours of 20 pixels or
/// more (the data: a bar or a line per series and its legend swatch). Returns what it found.
pub fn assert_plot(path: &Path, min_colours: usize) -> PlotContent {
    let img = read_png(path);
    let name = path.display();
    assert!(
        img.width >= 640 && img.height >= 400,
        "{name}: {}×{} is too small for a plot",
        img.width,
        img.height
    );
    let mut counts = std::collections::BTreeMap::<[u8; 3], usize>::new();
    for p in &img.rgb {
        *counts.entry(*p).or_default() += 1;
    }
    let (&background, &bg_count) = counts.iter().max_by_key(|(_, n)| **n).unwrap();
    let total = img.rgb.len();
    assert!(
        background.iter().all(|&c| c >= 240) && bg_count * 10 >= total * 3,
        "{name}: background {background:?} covers {bg_count} of {total} pixels"
    );
    let non_background = total - bg_count;
    assert!(
        non_background * 50 >= total,
        "{name}: only {non_background} of {total} pixels drawn"
    );
    let mut colours: Vec<([u8; 3], usize)> = counts
        .into_iter()
        .filter(|(c, n)| {
            let (max, min) = (c.iter().max().unwrap(), c.iter().min().unwrap());
            max - min >= 48 && *n >= 20
        })
        .collect();
    colours.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    assert!(
        colours.len() >= min_colours,
        "{name}: {} saturated colours ({colours:?}), expected at least {min_colours}",
        colours.len()
    );
    PlotContent {
        width: img.width,
        height: img.height,
        background,
        non_background,
        colours,
    }
}

/// How many colours bars drawn for `values` show: the bars cycle through the plots' 6 colours
/// in order, and a bar of height 0 shows none.
pub fn bar_colours(values: &[f64]) -> usize {
    let used: std::collections::BTreeSet<usize> = values
        .iter()
        .enumerate()
        .filter(|(_, v)| **v > 0.0)
        .map(|(i, _)| i % 6)
        .collect();
    used.len()
}

/// The plots of a sim run show its data: `success_by_category.png` a bar for every category
/// with a grasp success, `failure_reasons.png` one for every failure reason that occurred, in as
/// many colours as those bars use (both in the results' order).
pub fn assert_grasp_plots(dir: &Path, r: &serde_json::Value) {
    let s = &r["summary"];
    let succeeded: Vec<f64> = s["per_category"]
        .as_object()
        .unwrap()
        .values()
        .map(|c| c["grasp_success_rate"]["successes"].as_u64().unwrap() as f64)
        .collect();
    assert_plot(
        &dir.join("success_by_category.png"),
        bar_colours(&succeeded),
    );
    let failed: Vec<f64> = s["failure_reasons"]
        .as_object()
        .unwrap()
        .values()
        .map(|n| n.as_u64().unwrap() as f64)
        .collect();
    assert_plot(&dir.join("failure_reasons.png"), bar_colours(&failed));
}

/// Decodes a round's storyboard (`rounds/round-NNNN.png`: rendered camera views side by side)
/// and checks that it shows rendered scenes, not a blank canvas: at least 600 × 200 pixels, no
/// colour covering more than 60 % of it, and at least 100 distinct colours (shaded objects,
/// table, basket, captions).
pub fn assert_storyboard(path: &Path) {
    let img = read_png(path);
    let name = path.display();
    assert!(
        img.width >= 600 && img.height >= 200,
        "{name}: {}×{} is too small for a storyboard",
        img.width,
        img.height
    );
    let mut counts = std::collections::BTreeMap::<[u8; 3], usize>::new();
    for p in &img.rgb {
        *counts.entry(*p).or_default() += 1;
    }
    let commonest = counts.values().copied().max().unwrap();
    assert!(
        commonest * 10 <= img.rgb.len() * 6,
        "{name}: one colour covers {commonest} of {} pixels",
        img.rgb.len()
    );
    assert!(
        counts.len() >= 100,
        "{name}: only {} distinct colours: not a rendered scene",
        counts.len()
    );
}
