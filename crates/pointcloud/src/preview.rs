//! Preview images for people: `contact_sheet.png` (every object, one view each, labelled, all
//! at one scale with a size bar and each object's largest extent, so an object imported in the
//! wrong unit stands out) and `grasp_preview.png` (the first grasp-labelled scene, RGB and
//! depth, rectangles drawn).
//! The dataset generator writes both; this module does not depend on `dataset`.

use std::path::Path;

use crate::grasp::GraspSpec;
use crate::grasp::cornell::{GraspScene, OBJECT_LABEL, draw_rectangles, grasp_scene};
use crate::image::{ImageError, RgbImage, depth_to_gray};
use crate::math::{Pose, look_at};
use crate::objects::ObjectModel;
use crate::progress::Progress;
use crate::render::{Camera, Intrinsics, RenderItem, render};

/// File name of the contact sheet.
pub const CONTACT_SHEET: &str = "contact_sheet.png";
/// File name of the grasp preview.
pub const GRASP_PREVIEW: &str = "grasp_preview.png";

/// Width of a contact-sheet tile, pixels.
pub const TILE_W: usize = 200;
/// Height of a contact-sheet tile, pixels (the object's name goes below it).
pub const TILE_H: usize = 160;
const LABEL_H: usize = 16;
const SHEET_BG: [u8; 3] = [32, 34, 38];
const TILE_BG: [u8; 3] = [58, 62, 70];

/// Colour of the size bar drawn in every contact-sheet tile.
pub const SIZE_BAR_COLOR: [u8; 3] = [255, 196, 0];

/// The scale every tile of a contact sheet shares, so objects can be compared by size (an
/// object imported in the wrong unit stands out 10× too big or too small).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetScale {
    /// Metres per pixel at each object's centre, the same in every tile: chosen so the largest
    /// object fills its tile.
    pub metres_per_px: f32,
    /// Length of the size bar, metres (1, 2 or 5 × 10ⁿ: the longest that spans at most a
    /// third of the tile).
    pub bar_m: f32,
    /// Length of the size bar, pixels (`bar_m / metres_per_px`, rounded).
    pub bar_px: usize,
}

/// Focal length of a thumbnail camera, pixels.
fn thumbnail_focal(height: usize) -> f32 {
    height as f32 * 1.1
}

/// Bounding-box centre and bounding-sphere radius of an object, metres.
fn centre_and_radius(object: &ObjectModel) -> ([f32; 3], f32) {
    let (lo, hi) = object.mesh.bounds().unwrap_or(([0.0; 3], [0.1; 3]));
    let centre = [
        (lo[0] + hi[0]) / 2.0,
        (lo[1] + hi[1]) / 2.0,
        (lo[2] + hi[2]) / 2.0,
    ];
    let radius =
        0.5 * ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    (centre, radius)
}

/// Metres per pixel at which `object`'s bounding sphere just fits a tile `height` pixels high.
fn fitting_metres_per_px(object: &ObjectModel, height: usize) -> f32 {
    let focal = thumbnail_focal(height);
    let half_fov = (height as f32 / 2.0 / focal).atan();
    let (_, radius) = centre_and_radius(object);
    let distance = (radius / half_fov.sin()) * 1.05;
    distance / focal
}

/// The common scale of `objects` in `width × height` tiles: the largest object fills its tile.
pub fn sheet_scale(objects: &[ObjectModel], width: usize, height: usize) -> SheetScale {
    let metres_per_px = objects
        .iter()
        .map(|o| fitting_metres_per_px(o, height))
        .filter(|m| m.is_finite() && *m > 0.0)
        .fold(f32::MIN_POSITIVE, f32::max);
    const NICE_M: [f32; 16] = [
        0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0,
        100.0,
    ];
    let max_px = (width / 3).max(1) as f32;
    let bar_m = NICE_M
        .into_iter()
        .rev()
        .find(|&m| m / metres_per_px <= max_px)
        .unwrap_or(NICE_M[0]);
    SheetScale {
        metres_per_px,
        bar_m,
        bar_px: (bar_m / metres_per_px).round().max(1.0) as usize,
    }
}

/// A length for people: `1.5 m`, `43 cm`, `9.5 cm`, `4 mm`.
fn format_length(m: f32) -> String {
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    if m >= 1.0 {
        format!("{} m", trim(format!("{m:.2}")))
    } else if m >= 0.01 {
        format!("{} cm", trim(format!("{:.1}", m * 100.0)))
    } else {
        format!("{} mm", trim(format!("{:.1}", m * 1000.0)))
    }
}

/// One view of an object filling a `width × height` tile: camera at 30° elevation, distance
/// chosen so the bounding sphere fits.
pub fn object_thumbnail(object: &ObjectModel, width: usize, height: usize) -> RgbImage {
    object_thumbnail_at(object, width, height, fitting_metres_per_px(object, height))
}

/// One view of an object in a `width × height` tile at `metres_per_px` (at the object's
/// centre): camera at 30° elevation looking at the centre of the bounding box.
pub fn object_thumbnail_at(
    object: &ObjectModel,
    width: usize,
    height: usize,
    metres_per_px: f32,
) -> RgbImage {
    let (centre, _) = centre_and_radius(object);
    let focal = thumbnail_focal(height);
    let distance = metres_per_px * focal;
    let (s, c) = 30f32.to_radians().sin_cos();
    // Looking from -y, slightly turned so handles and spouts show.
    let dir = [0.35 * c, -c, s];
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    let eye = [
        centre[0] + distance * dir[0] / n,
        centre[1] + distance * dir[1] / n,
        centre[2] + distance * dir[2] / n,
    ];
    let camera = Camera::new(
        Intrinsics::centered(width as u32, height as u32, focal),
        look_at(eye, centre, [0.0, 0.0, 1.0]),
    );
    let frame = render(
        &camera,
        &[RenderItem {
            mesh: &object.mesh,
            world_from_object: Pose::identity(),
            label: 1,
        }],
    );
    let data = frame
        .rgb
        .iter()
        .zip(&frame.label)
        .map(|(&c, &l)| if l == 0 { TILE_BG } else { c })
        .collect();
    RgbImage::from_pixels(width, height, data)
}

/// The contact-sheet tiles (`TILE_W × TILE_H` each, in object order) at one common scale:
/// each shows its object, the size bar ([`SIZE_BAR_COLOR`], `scale.bar_px` long, 3 px thick,
/// bottom left, labelled) and the object's largest extent (top right).
pub fn contact_sheet_tiles(objects: &[ObjectModel]) -> (SheetScale, Vec<RgbImage>) {
    let scale = sheet_scale(objects, TILE_W, TILE_H);
    let tiles = objects
        .iter()
        .map(|o| {
            let mut tile = object_thumbnail_at(o, TILE_W, TILE_H, scale.metres_per_px);
            let (x0, y0) = (6i64, (TILE_H - 8) as i64);
            for dy in 0..3 {
                for dx in 0..scale.bar_px as i64 {
                    tile.put(x0 + dx, y0 + dy, SIZE_BAR_COLOR);
                }
            }
            tile.draw_text(x0, y0 - 10, &format_length(scale.bar_m), [235, 235, 235], 1);
            let extent = o
                .mesh
                .bounds()
                .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max))
                .unwrap_or(0.0);
            let text = format_length(extent);
            let tw = RgbImage::text_width(&text, 1);
            tile.draw_text(
                TILE_W.saturating_sub(tw + 6) as i64,
                5,
                &text,
                [235, 235, 235],
                1,
            );
            tile
        })
        .collect();
    (scale, tiles)
}

/// The contact sheet: one labelled tile per object, all at one scale with a size bar (see
/// [`contact_sheet_tiles`]), one row per category when every category has the same number of
/// instances (at most 10), else a square-ish grid.
pub fn contact_sheet(objects: &[ObjectModel], title: &str) -> RgbImage {
    let mut categories: Vec<&str> = Vec::new();
    for o in objects {
        if !categories.contains(&o.category.as_str()) {
            categories.push(&o.category);
        }
    }
    let per_cat: Vec<usize> = categories
        .iter()
        .map(|c| objects.iter().filter(|o| o.category == *c).count())
        .collect();
    let uniform =
        per_cat.windows(2).all(|w| w[0] == w[1]) && per_cat.first().is_some_and(|&n| n <= 10);
    let cols = if uniform {
        per_cat[0]
    } else {
        (objects.len() as f32).sqrt().ceil() as usize
    }
    .max(1);
    let rows = objects.len().div_ceil(cols);
    let (scale, tiles) = contact_sheet_tiles(objects);
    let note = format!(
        "one scale for all tiles: bar = {}",
        format_length(scale.bar_m)
    );
    let header = 40;
    let text_w = RgbImage::text_width(title, 2).max(RgbImage::text_width(&note, 1)) + 16;
    let (w, h) = (
        (cols * TILE_W + (cols + 1) * 4).max(text_w),
        header + rows * (TILE_H + LABEL_H) + (rows + 1) * 4,
    );
    let mut sheet = RgbImage::new(w, h, SHEET_BG);
    sheet.draw_text(8, 8, title, [230, 230, 230], 2);
    sheet.draw_text(8, 28, &note, SIZE_BAR_COLOR, 1);
    for (i, (o, tile)) in objects.iter().zip(&tiles).enumerate() {
        let (r, c) = (i / cols, i % cols);
        let x = 4 + c * (TILE_W + 4);
        let y = header + 4 + r * (TILE_H + LABEL_H + 4);
        sheet.blit(tile, x as i64, y as i64);
        let label = &o.name;
        let tw = RgbImage::text_width(label, 1);
        sheet.draw_text(
            (x + TILE_W.saturating_sub(tw) / 2) as i64,
            (y + TILE_H + 4) as i64,
            label,
            [220, 220, 220],
            1,
        );
    }
    sheet
}

/// Writes the preview PNGs of a dataset made with `seed` and the grasp parameters `grasp` into
/// `out_dir` — the contact sheet, and the grasp preview when `grasp_images` (the dataset has grasp
/// images to preview) — and returns their paths relative to `out_dir`.
pub fn write_previews(
    objects: &[ObjectModel],
    seed: u64,
    grasp: &GraspSpec,
    grasp_images: bool,
    out_dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Vec<String>, ImageError> {
    if objects.is_empty() {
        return Ok(Vec::new());
    }
    let total = 1 + u64::from(grasp_images);
    let title = format!("lgdm dataset: {} objects, seed {}", objects.len(), seed);
    contact_sheet(objects, &title).write_png(&out_dir.join(CONTACT_SHEET))?;
    progress(Progress {
        stage: "previews",
        done: 1,
        total,
    });
    if !grasp_images {
        return Ok(vec![CONTACT_SHEET.to_string()]);
    }
    // The first grasp scene (the same one the Cornell export wrote as pcd0100).
    let scene = grasp_scene(grasp, seed, 0, &objects[0]);
    grasp_preview(&scene, &objects[0].name).write_png(&out_dir.join(GRASP_PREVIEW))?;
    progress(Progress {
        stage: "previews",
        done: 2,
        total,
    });
    Ok(vec![CONTACT_SHEET.to_string(), GRASP_PREVIEW.to_string()])
}

/// RGB (left) and depth (right) of a grasp scene with its rectangles drawn, cropped around the
/// object and enlarged 2×.
pub fn grasp_preview(scene: &GraspScene, name: &str) -> RgbImage {
    let f = &scene.frame;
    let (w, h) = (f.width as usize, f.height as usize);
    let (pos, neg) = (scene.positives(), scene.negatives());
    let mut rgb = RgbImage::from_pixels(w, h, f.rgb.clone());
    draw_rectangles(&mut rgb, &pos, &neg);
    let mut depth = depth_to_gray(&f.depth_m, w, h);
    draw_rectangles(&mut depth, &pos, &neg);
    // Crop a square around the object's pixels.
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for (i, &l) in f.label.iter().enumerate() {
        if l == OBJECT_LABEL {
            let (x, y) = (i % w, i / w);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
    }
    let side = if x1 >= x0 {
        ((x1 - x0).max(y1 - y0) + 80).clamp(160, h)
    } else {
        h
    };
    let cx = if x1 >= x0 { (x0 + x1) / 2 } else { w / 2 };
    let cy = if y1 >= y0 { (y0 + y1) / 2 } else { h / 2 };
    let (ox, oy) = (cx as i64 - side as i64 / 2, cy as i64 - side as i64 / 2);
    let factor = if side <= 320 { 2 } else { 1 };
    let rgb = rgb.crop(ox, oy, side, side).upscale(factor);
    let depth = depth.crop(ox, oy, side, side).upscale(factor);
    let mut out = RgbImage::new(2 * rgb.width + 4, rgb.height + 24, SHEET_BG);
    out.blit(&rgb, 0, 24);
    out.blit(&depth, (rgb.width + 4) as i64, 24);
    let text = format!(
        "{name}: {} positive (green, blue jaws), {} negative (red)",
        pos.len(),
        neg.len()
    );
    out.draw_text(6, 8, &text, [230, 230, 230], 1);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::procedural_library;

    #[test]
    fn the_grasp_preview_is_written_only_for_a_dataset_with_grasp_images() {
        let objects = procedural_library(&["mug", "can"], 1, 0).unwrap();
        let grasp = GraspSpec::default();
        for (with, files) in [
            (false, vec![CONTACT_SHEET]),
            (true, vec![CONTACT_SHEET, GRASP_PREVIEW]),
        ] {
            let dir = tempfile::tempdir().unwrap();
            let mut last = None;
            let written = write_previews(&objects, 0, &grasp, with, dir.path(), &mut |p| {
                last = Some(p)
            })
            .unwrap();
            assert_eq!(written, files);
            assert_eq!(dir.path().join(GRASP_PREVIEW).exists(), with);
            let last = last.unwrap();
            assert_eq!(
                (last.done, last.total),
                (files.len() as u64, files.len() as u64)
            );
        }
    }
}
