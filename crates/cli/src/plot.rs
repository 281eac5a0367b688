//! PNG plots of a run in the style of the paper's figures: a mean line per series over
//! steps with a shaded ± std band across trials, and per-category test accuracy bars.

use anyhow::{Result, anyhow};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

use lgdm_gdm::experiment::{MeanStd, RunMetrics, StepRecord};

const WIDTH: u32 = 800;
const HEIGHT: u32 = 500;
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is embedded and known good; a failure here would only lose the labels.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One series over steps: (step, mean, std) where the step was measured.
struct Series {
    name: String,
    points: Vec<(f64, MeanStd)>,
}

/// Collects a per-step figure over trials; steps where any trial lacks it are skipped.
fn series(m: &RunMetrics, name: &str, f: impl Fn(&StepRecord) -> Option<f64>) -> Series {
    let steps = m.trials.iter().map(|t| t.steps.len()).min().unwrap_or(0);
    let mut points = Vec::new();
    for k in 0..steps {
        let vals: Option<Vec<f64>> = m.trials.iter().map(|t| f(&t.steps[k])).collect();
        if let Some(vals) = vals {
            points.push(((k + 1) as f64, MeanStd::of(&vals)));
        }
    }
    Series {
        name: name.to_string(),
        points,
    }
}

fn write_png(path: &Path, buf: &[u8]) -> Result<()> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, WIDTH, HEIGHT);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header()?;
        w.write_image_data(buf)?;
        w.finish()?;
    }
    lgdm_gdm::experiment::run_dir::write_atomic(path, &bytes)?;
    Ok(())
}

/// A line chart of named series of (x, y) points (no bands); `unit_range` fixes y to [0, 1].
pub fn write_lines(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    lines: &[(String, Vec<(f64, f64)>)],
    unit_range: bool,
) -> Result<()> {
    let all: Vec<Series> = lines
        .iter()
        .map(|(name, points)| Series {
            name: name.clone(),
            points: points
                .iter()
                .map(|&(x, y)| (x, MeanStd { mean: y, std: 0.0 }))
                .collect(),
        })
        .collect();
    line_chart(path, title, x_desc, y_desc, &all, unit_range)
}

fn line_chart(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    all: &[Series],
    unit_range: bool,
) -> Result<()> {
    register_font();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let x_max = all
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .fold(1.0, f64::max);
        let y_max = if unit_range {
            1.0
        } else {
            all.iter()
                .flat_map(|s| s.points.iter().map(|p| p.1.mean + p.1.std))
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
                * 1.1
                + 1e-9
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5f64..x_max + 0.5, 0f64..y_max)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (i, s) in all.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            if s.points.is_empty() {
                continue;
            }
            let mut band: Vec<(f64, f64)> =
                s.points.iter().map(|(x, m)| (*x, m.mean + m.std)).collect();
            band.extend(
                s.points
                    .iter()
                    .rev()
                    .map(|(x, m)| (*x, (m.mean - m.std).max(0.0))),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(band, color.mix(0.2).filled())))
                .map_err(|e| anyhow!("{e}"))?;
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().map(|(x, m)| (*x, m.mean)),
                    color.stroke_width(2),
                ))
                .map_err(|e| anyhow!("{e}"))?
                .label(s.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    write_png(path, &buf)
}

fn category_bars(path: &Path, m: &RunMetrics) -> Result<()> {
    register_font();
    let n = m.categories.len();
    let stats: Vec<Option<MeanStd>> = (0..n)
        .map(|c| {
            let vals: Vec<f64> = m
                .trials
                .iter()
                .filter_map(|t| t.per_category_test_accuracy.get(c).copied().flatten())
                .collect();
            (!vals.is_empty()).then(|| MeanStd::of(&vals))
        })
        .collect();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let names = m.categories.clone();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Test category accuracy (G-SM) per category",
                ("sans-serif", 22),
            )
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0f64..1.05)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n.max(1))
            .x_label_formatter(&|x| bar_label(&names, *x))
            .y_desc("accuracy")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (c, s) in stats.iter().enumerate() {
            let Some(s) = s else { continue };
            let x = c as f64;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x - 0.35, 0.0), (x + 0.35, s.mean)],
                    PALETTE[0].filled(),
                )))
                .map_err(|e| anyhow!("{e}"))?;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![
                        (x, (s.mean - s.std).max(0.0)),
                        (x, (s.mean + s.std).min(1.05)),
                    ],
                    BLACK.stroke_width(2),
                )))
                .map_err(|e| anyhow!("{e}"))?;
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    write_png(path, &buf)
}

/// Writes `nodes.png`, `accuracy.png`, `quantization_error.png` and
/// `category_accuracy.png` into `dir`; returns their names.
pub fn write_run_plots(dir: &Path, m: &RunMetrics) -> Result<Vec<String>> {
    let x_desc = if m.scenario == "batch" {
        "epoch"
    } else {
        "step (episode / mini-batch)"
    };
    line_chart(
        &dir.join("nodes.png"),
        "Number of nodes",
        x_desc,
        "nodes",
        &[
            series(m, "G-EM", |s| Some(s.episodic_nodes as f64)),
            series(m, "G-SM", |s| Some(s.semantic_nodes as f64)),
        ],
        false,
    )?;
    line_chart(
        &dir.join("accuracy.png"),
        "Accuracy",
        x_desc,
        "accuracy",
        &[
            series(m, "train instance (G-EM)", |s| {
                s.train.as_ref().map(|f| f.instance_accuracy)
            }),
            series(m, "train category (G-SM)", |s| {
                s.train.as_ref().map(|f| f.category_accuracy_sm)
            }),
            series(m, "test instance (G-EM)", |s| {
                s.test.as_ref().map(|f| f.instance_accuracy)
            }),
            series(m, "test category (G-EM)", |s| {
                s.test.as_ref().map(|f| f.category_accuracy_em)
            }),
            series(m, "test category (G-SM)", |s| {
                s.test.as_ref().map(|f| f.category_accuracy_sm)
            }),
        ],
        true,
    )?;
    line_chart(
        &dir.join("quantization_error.png"),
        "Average quantization error",
        x_desc,
        "quantization error",
        &[
            series(m, "G-EM", |s| Some(s.quantization_error_em)),
            series(m, "G-SM", |s| Some(s.quantization_error_sm)),
        ],
        false,
    )?;
    category_bars(&dir.join("category_accuracy.png"), m)?;
    Ok(vec![
        "nodes.png".into(),
        "accuracy.png".into(),
        "quantization_error.png".into(),
        "category_accuracy.png".into(),
    ])
}

/// Writes a confusion matrix (rows: true category, columns: predicted) as a PNG heat map.
pub fn write_confusion_png(path: &Path, names: &[String], counts: &[Vec<u64>]) -> Result<()> {
    register_font();
    let n = names.len();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let names_x = names.to_vec();
        let names_y = names.to_vec();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Category confusion (rows: true, columns: predicted)",
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(100)
            .build_cartesian_2d(-0.5f64..n as f64 - 0.5, n as f64 - 0.5..-0.5f64)
            .map_err(|e| anyhow!("{e}"))?;
        let fmt = |names: &Vec<String>, v: &f64| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(n.max(1))
            .y_labels(n.max(1))
            .x_label_formatter(&|v| fmt(&names_x, v))
            .y_label_formatter(&|v| fmt(&names_y, v))
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (r, row) in counts.iter().enumerate() {
            let total: u64 = row.iter().sum();
            for (c, &v) in row.iter().enumerate() {
                let frac = if total == 0 {
                    0.0
                } else {
                    v as f64 / total as f64
                };
                let shade = (255.0 * (1.0 - frac)) as u8;
                let (x, y) = (c as f64, r as f64);
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)],
                        RGBColor(shade, shade, 255).filled(),
                    )))
                    .map_err(|e| anyhow!("{e}"))?;
                if v > 0 {
                    let color = if frac > 0.5 { WHITE } else { BLACK };
                    chart
                        .draw_series(std::iter::once(Text::new(
                            v.to_string(),
                            (x - 0.2, y - 0.15),
                            ("sans-serif", 12).into_font().color(&color),
                        )))
                        .map_err(|e| anyhow!("{e}"))?;
                }
            }
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    write_png(path, &buf)
}

/// One bar of [`write_bar_chart`]: a label, a value and an optional interval drawn as a whisker.
#[derive(Debug, Clone)]
pub struct Bar {
    /// The label under the bar.
    pub label: String,
    /// The bar's height.
    pub value: f64,
    /// A (low, high) whisker, e.g. a Wilson interval.
    pub interval: Option<(f64, f64)>,
}

/// Writes a bar chart (one bar per entry, optional whiskers) as a PNG; `y_max` is the top of
/// the value axis.
pub fn write_bar_chart(
    path: &Path,
    title: &str,
    y_desc: &str,
    bars: &[Bar],
    y_max: f64,
) -> Result<()> {
    register_font();
    let n = bars.len();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let names: Vec<String> = bars.iter().map(|b| b.label.clone()).collect();
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..n.max(1) as f64 - 0.5, 0f64..y_max)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n.max(1))
            .x_label_formatter(&|x| bar_label(&names, *x))
            .y_desc(y_desc)
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (i, b) in bars.iter().enumerate() {
            let x = i as f64;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x - 0.35, 0.0), (x + 0.35, b.value.min(y_max))],
                    PALETTE[i % PALETTE.len()].filled(),
                )))
                .map_err(|e| anyhow!("{e}"))?;
            if let Some((lo, hi)) = b.interval {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x, lo.max(0.0)), (x, hi.min(y_max))],
                        BLACK.stroke_width(2),
                    )))
                    .map_err(|e| anyhow!("{e}"))?;
            }
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    write_png(path, &buf)
}

/// The name of the bar at x (bars sit at 0, 1, …); empty between bars.
fn bar_label(names: &[String], x: f64) -> String {
    let i = x.round();
    if (x - i).abs() < 1e-6 && i >= 0.0 {
        names.get(i as usize).cloned().unwrap_or_default()
    } else {
        String::new()
    }
}
