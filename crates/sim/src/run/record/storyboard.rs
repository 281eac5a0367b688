//! The PNG storyboard of a recorded round: one row per attempt (the crop with the chosen grasp,
//! the overview before and after, the basket after) and its caption.

use lgdm_pointcloud::grasp::GraspRectangle;
use lgdm_pointcloud::image::RgbImage;
use lgdm_pointcloud::math::{Pose, transform_point};
use lgdm_pointcloud::render::Camera;

use crate::grasping::attempt::Execution;
use crate::perception::camera::SceneFrame;
use crate::run::observe::GraspShown;

/// What the storyboard shows of one attempt.
#[derive(Debug, Clone, Default)]
pub(super) struct StoryRow {
    pub(super) panels: Vec<(String, RgbImage)>,
    pub(super) caption: String,
}

/// `grasp ok, placed` / `grasp ok, not placed (dropped_outside)` / `failed (missed)`.
pub fn outcome_text(exec: &Execution) -> String {
    let reason = exec.reason.map(|r| r.as_str()).unwrap_or("unknown");
    match (exec.grasp_success, exec.placement_success) {
        (true, true) => "grasp ok, placed".into(),
        (true, false) => format!("grasp ok, not placed ({reason})"),
        _ => format!("grasp failed ({reason})"),
    }
}

pub(super) fn frame_image(shot: &SceneFrame) -> RgbImage {
    let f = &shot.frame;
    RgbImage::from_pixels(f.width as usize, f.height as usize, f.rgb.clone())
}

/// The planned grasp's jaw rectangle (predicted opening × finger width, at the grasp point)
/// projected into `camera`'s image, Cornell corner order.
pub(super) fn project_grasp(camera: &Camera, shown: &GraspShown<'_>) -> Option<GraspRectangle> {
    let g = &shown.plan.grasp;
    let (s, c) = g.yaw_rad.sin_cos();
    let (o, w) = (
        0.5 * g.opening_m,
        0.5 * f64::from(shown.gripper.finger_width_m),
    );
    let camera_from_world: Pose = camera.world_from_camera.inverse();
    let corner = |a: f64, b: f64| {
        let p = [
            g.position_m[0] + a * o * c - b * w * s,
            g.position_m[1] + a * o * s + b * w * c,
            g.position_m[2],
        ];
        camera
            .intrinsics
            .project(transform_point(&camera_from_world, p.map(|v| v as f32)))
    };
    Some(GraspRectangle {
        corners_px: [
            corner(-1.0, -1.0)?,
            corner(1.0, -1.0)?,
            corner(1.0, 1.0)?,
            corner(-1.0, 1.0)?,
        ],
    })
}

pub(super) const STORY_BG: [u8; 3] = [32, 34, 38];
pub(super) const STORY_TEXT: [u8; 3] = [230, 230, 230];
pub(super) const STORY_LABEL: [u8; 3] = [160, 170, 180];
pub(super) const GAP: usize = 6;

/// The storyboard: a title line, then per attempt a caption line, panel labels and the panels
/// left to right.
pub(super) fn compose_storyboard(title: &str, rows: &[StoryRow]) -> RgbImage {
    const LINE: usize = 12;
    let row_width = |r: &StoryRow| {
        let panels = GAP + r.panels.iter().map(|(_, p)| p.width + GAP).sum::<usize>();
        panels.max(RgbImage::text_width(&r.caption, 1) + 2 * GAP)
    };
    let width = rows
        .iter()
        .map(row_width)
        .chain([RgbImage::text_width(title, 1) + 2 * GAP, 240])
        .max()
        .unwrap_or(240);
    let row_height =
        |r: &StoryRow| 2 * LINE + r.panels.iter().map(|(_, p)| p.height).max().unwrap_or(0) + GAP;
    let height = LINE + GAP + rows.iter().map(row_height).sum::<usize>();
    let mut img = RgbImage::new(width, height, STORY_BG);
    img.draw_text(GAP as i64, 4, title, STORY_TEXT, 1);
    let mut y = LINE + GAP;
    for r in rows {
        img.draw_text(GAP as i64, y as i64, &r.caption, STORY_TEXT, 1);
        let mut x = GAP;
        for (label, panel) in &r.panels {
            img.draw_text(x as i64, (y + LINE) as i64, label, STORY_LABEL, 1);
            img.blit(panel, x as i64, (y + 2 * LINE) as i64);
            x += panel.width + GAP;
        }
        y += row_height(r);
    }
    img
}
