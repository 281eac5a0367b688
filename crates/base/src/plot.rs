//! PNG charts in the style of the paper's figures, drawn with plotters into a buffer and written
//! atomically ([`crate::fs::write_bytes`]): line charts with a shaded band per series
//! ([`line_chart`]), bar charts with whiskers ([`bar_chart`]), heat maps of counts
//! ([`heat_map`]) and of values in [0, 1] ([`value_heat_map`]). The run directories' plots are drawn with these —
//! `lgdm_gdm::experiment::plots` for training runs and `lgdm_sim::run::plots` for robot runs —
//! whoever writes the run, the binary or the Python module. Errors come back as [`io::Error`].
//!
//! ```
//! use lgdm_base::plot::{Bar, Line, bar_chart, line_chart};
//! let dir = tempfile::tempdir().unwrap();
//! let line = Line { name: "G-EM".into(), points: vec![(1.0, 3.0, 0.5), (2.0, 5.0, 1.0)] };
//! line_chart(&dir.path().join("nodes.png"), "Nodes", "step", "nodes", &[line], false).unwrap();
//! let bar = Bar { label: "mug".into(), value: 0.8, interval: Some((0.6, 0.9)) };
//! bar_chart(&dir.path().join("bars.png"), "Success", "share", &[bar], 1.05).unwrap();
//! assert!(dir.path().join("bars.png").metadata().unwrap().len() > 0);
//! ```

use plotters::prelude::*;
use std::io;
use std::path::Path;
use std::sync::Once;

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

/// A drawing error as an [`io::Error`].
fn draw_error(e: impl std::fmt::Display) -> io::Error {
    io::Error::other(format!("drawing the chart: {e}"))
}

fn write_png(path: &Path, buf: &[u8]) -> io::Result<()> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, WIDTH, HEIGHT);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(io::Error::other)?;
        w.write_image_data(buf).map_err(io::Error::other)?;
        w.finish().map_err(io::Error::other)?;
    }
    crate::fs::write_bytes(path, &bytes)
}

/// One series of a [`line_chart`]: its legend name and its points `(x, y, band)`, drawn as a
/// line through `y` with a shaded band `y ± band` (0 for none; the band stops at 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// The legend's name.
    pub name: String,
    /// `(x, y, band)` per point, in x order.
    pub points: Vec<(f64, f64, f64)>,
}

/// Writes a line chart of `lines` as a PNG. `unit_range` fixes y to [0, 1]; otherwise y runs
/// from 0 to a tenth above the highest band. x starts at 0.5 (steps count from 1).
pub fn line_chart(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    lines: &[Line],
    unit_range: bool,
) -> io::Result<()> {
    register_font();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let x_max = lines
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .fold(1.0, f64::max);
        let y_max = if unit_range {
            1.0
        } else {
            lines
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1 + p.2))
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
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(draw_error)?;
        for (i, s) in lines.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            if s.points.is_empty() {
                continue;
            }
            let mut band: Vec<(f64, f64)> = s.points.iter().map(|&(x, y, b)| (x, y + b)).collect();
            band.extend(
                s.points
                    .iter()
                    .rev()
                    .map(|&(x, y, b)| (x, (y - b).max(0.0))),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(band, color.mix(0.2).filled())))
                .map_err(draw_error)?;
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().map(|&(x, y, _)| (x, y)),
                    color.stroke_width(2),
                ))
                .map_err(draw_error)?
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
            .map_err(draw_error)?;
        root.present().map_err(draw_error)?;
    }
    write_png(path, &buf)
}

/// One bar of [`bar_chart`]: a label, a value and an optional interval drawn as a whisker.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    /// The label under the bar.
    pub label: String,
    /// The bar's height; a value that is not finite leaves the bar's place empty.
    pub value: f64,
    /// A (low, high) whisker, e.g. a Wilson interval.
    pub interval: Option<(f64, f64)>,
}

/// Writes a bar chart (one bar per entry, optional whiskers) as a PNG; `y_max` is the top of
/// the value axis.
pub fn bar_chart(
    path: &Path,
    title: &str,
    y_desc: &str,
    bars: &[Bar],
    y_max: f64,
) -> io::Result<()> {
    register_font();
    let n = bars.len();
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let names: Vec<String> = bars.iter().map(|b| b.label.clone()).collect();
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..n.max(1) as f64 - 0.5, 0f64..y_max)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n.max(1))
            .x_label_formatter(&|x| tick_name(&names, *x))
            .y_desc(y_desc)
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(draw_error)?;
        for (i, b) in bars.iter().enumerate() {
            if !b.value.is_finite() {
                continue;
            }
            let x = i as f64;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x - 0.35, 0.0), (x + 0.35, b.value.min(y_max))],
                    PALETTE[i % PALETTE.len()].filled(),
                )))
                .map_err(draw_error)?;
            if let Some((lo, hi)) = b.interval {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x, lo.max(0.0)), (x, hi.min(y_max))],
                        BLACK.stroke_width(2),
                    )))
                    .map_err(draw_error)?;
            }
        }
        root.present().map_err(draw_error)?;
    }
    write_png(path, &buf)
}

/// Writes `counts` (rows: true, columns: predicted, in the order of `names`) as a PNG heat map,
/// each row shaded by its share and each non-zero cell labelled with its count.
pub fn heat_map(path: &Path, title: &str, names: &[String], counts: &[Vec<u64>]) -> io::Result<()> {
    let cells: Vec<Vec<Option<Cell>>> = counts
        .iter()
        .map(|row| {
            let total: u64 = row.iter().sum();
            row.iter()
                .map(|&v| {
                    let share = if total == 0 {
                        0.0
                    } else {
                        v as f64 / total as f64
                    };
                    Some(Cell {
                        shade: share,
                        text: (v > 0).then(|| v.to_string()),
                    })
                })
                .collect()
        })
        .collect();
    grid(path, title, None, names, names, &cells)
}

/// Grids larger than this many rows or columns leave their cells unlabelled.
const LABELLED_GRID: usize = 12;

/// Writes `values` (rows top to bottom as `row_names`, columns left to right as
/// `column_names`) as a PNG heat map shaded by value on a fixed [0, 1] scale (white 0, dark
/// blue 1), each cell labelled in per cent while the grid has at most 12 rows and columns.
/// `None`, or a value that is not finite, leaves its cell empty (grey). The axes are described
/// by `x_desc` and `y_desc`.
pub fn value_heat_map(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    row_names: &[String],
    column_names: &[String],
    values: &[Vec<Option<f64>>],
) -> io::Result<()> {
    let labelled = row_names.len().max(column_names.len()) <= LABELLED_GRID;
    let cells: Vec<Vec<Option<Cell>>> = values
        .iter()
        .map(|row| {
            row.iter()
                .map(|v| {
                    v.filter(|v| v.is_finite()).map(|v| Cell {
                        shade: v.clamp(0.0, 1.0),
                        text: labelled.then(|| format!("{:.0}", 100.0 * v)),
                    })
                })
                .collect()
        })
        .collect();
    grid(
        path,
        title,
        Some((x_desc, y_desc)),
        row_names,
        column_names,
        &cells,
    )
}

/// One cell of [`grid`]: its shade in [0, 1] and its label.
struct Cell {
    shade: f64,
    text: Option<String>,
}

/// The name of tick `v` among `names` (ticks sit at 0, 1, …); empty between ticks.
fn tick_name(names: &[String], v: f64) -> String {
    let i = v.round();
    if (v - i).abs() < 1e-6 && i >= 0.0 {
        names.get(i as usize).cloned().unwrap_or_default()
    } else {
        String::new()
    }
}

/// Draws a grid of shaded cells (`None`: an empty, grey cell) with row and column names.
fn grid(
    path: &Path,
    title: &str,
    desc: Option<(&str, &str)>,
    row_names: &[String],
    column_names: &[String],
    cells: &[Vec<Option<Cell>>],
) -> io::Result<()> {
    register_font();
    let (rows, columns) = (row_names.len(), column_names.len());
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(100)
            .build_cartesian_2d(-0.5f64..columns as f64 - 0.5, rows as f64 - 0.5..-0.5f64)
            .map_err(draw_error)?;
        let column_tick = |v: &f64| tick_name(column_names, *v);
        let row_tick = |v: &f64| tick_name(row_names, *v);
        let mut mesh = chart.configure_mesh();
        mesh.disable_mesh()
            .x_labels(columns.clamp(1, 2 * LABELLED_GRID))
            .y_labels(rows.clamp(1, 2 * LABELLED_GRID))
            .x_label_formatter(&column_tick)
            .y_label_formatter(&row_tick)
            .label_style(("sans-serif", 12));
        if let Some((x_desc, y_desc)) = desc {
            mesh.x_desc(x_desc).y_desc(y_desc);
        }
        mesh.draw().map_err(draw_error)?;
        for (r, row) in cells.iter().enumerate() {
            for (c, cell) in row.iter().enumerate() {
                let (x, y) = (c as f64, r as f64);
                let fill = match cell {
                    Some(cell) => {
                        let shade = (255.0 * (1.0 - cell.shade)) as u8;
                        RGBColor(shade, shade, 255)
                    }
                    None => RGBColor(235, 235, 235),
                };
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)],
                        fill.filled(),
                    )))
                    .map_err(draw_error)?;
                if let Some(Cell {
                    shade,
                    text: Some(text),
                }) = cell
                {
                    let color = if *shade > 0.5 { WHITE } else { BLACK };
                    chart
                        .draw_series(std::iter::once(Text::new(
                            text.clone(),
                            (x - 0.2, y - 0.15),
                            ("sans-serif", 12).into_font().color(&color),
                        )))
                        .map_err(draw_error)?;
                }
            }
        }
        root.present().map_err(draw_error)?;
    }
    write_png(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
        let decoder = png::Decoder::new(io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    #[test]
    fn charts_are_pngs_that_show_their_data_and_repeat_to_the_byte() {
        let dir = tempfile::tempdir().unwrap();
        let bars = |v: f64| {
            vec![
                Bar {
                    label: "a".into(),
                    value: v,
                    interval: Some((v - 0.1, v + 0.1)),
                },
                Bar {
                    label: "missing".into(),
                    value: f64::NAN,
                    interval: None,
                },
            ]
        };
        let (low, high) = (dir.path().join("low.png"), dir.path().join("high.png"));
        bar_chart(&low, "t", "y", &bars(0.2), 1.05).unwrap();
        bar_chart(&high, "t", "y", &bars(0.9), 1.05).unwrap();
        let (w, h, a) = decode(&low);
        assert_eq!((w, h), (WIDTH, HEIGHT));
        let (_, _, b) = decode(&high);
        // A taller bar paints more of the first palette colour.
        let blue = |px: &[u8]| px.chunks(3).filter(|p| p == &[31, 119, 180]).count();
        assert!(blue(&b) > blue(&a) * 3, "{} vs {}", blue(&b), blue(&a));
        let again = dir.path().join("again.png");
        bar_chart(&again, "t", "y", &bars(0.2), 1.05).unwrap();
        assert_eq!(std::fs::read(&low).unwrap(), std::fs::read(&again).unwrap());

        let names = vec!["mug".to_string(), "can".to_string()];
        let map = dir.path().join("map.png");
        heat_map(&map, "confusion", &names, &[vec![3, 1], vec![0, 4]]).unwrap();
        let grid = |v: f64| {
            let (low, high) = (dir.path().join("g-low.png"), dir.path().join("g-high.png"));
            let values = vec![vec![Some(v), None], vec![Some(v), Some(f64::NAN)]];
            let path = if v < 0.5 { low } else { high };
            value_heat_map(&path, "R", "task", "after task", &names, &names, &values).unwrap();
            decode(&path).2
        };
        // A higher value paints darker blue cells; an empty cell is grey.
        let dark = |px: &[u8]| px.chunks(3).filter(|p| p[2] == 255 && p[0] < 100).count();
        let grey = |px: &[u8]| px.chunks(3).filter(|p| p == &[235, 235, 235]).count();
        let (lo, hi) = (grid(0.1), grid(0.9));
        assert!(
            dark(&hi) > dark(&lo) + 1000,
            "{} vs {}",
            dark(&hi),
            dark(&lo)
        );
        assert!(grey(&lo) > 1000, "empty cells are grey");
        assert_eq!(grid(0.1), lo, "same values, same bytes");
        let line = Line {
            name: "x".into(),
            points: vec![(1.0, 0.5, 0.1), (2.0, 0.7, 0.0)],
        };
        line_chart(&dir.path().join("l.png"), "t", "x", "y", &[line], true).unwrap();
    }

    #[test]
    fn a_chart_that_cannot_be_written_is_an_error_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/folder/x.png");
        let bar = Bar {
            label: "a".into(),
            value: 1.0,
            interval: None,
        };
        assert!(bar_chart(&path, "t", "y", &[bar], 1.05).is_err());
        assert!(!dir.path().join("no").exists());
    }
}
