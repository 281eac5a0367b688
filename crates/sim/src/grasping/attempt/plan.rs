//! A grasp turned into tool targets ([`GraspPlan`]): the commanded opening, the fingertip height
//! from the close-up's depth (clear of the table, the fingers' lanes and the palm's footprint),
//! the pre-grasp height, and whether both pads close on something.

use lgdm_pointcloud::math::transform_point;
use serde::{Deserialize, Serialize};

use crate::perception::{ObjectView, WorldGrasp};
use crate::robot::gripper::GripperConfig;

use super::config::AttemptConfig;
use super::motion::Cell;

/// A grasp turned into tool targets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspPlan {
    /// The grasp it came from.
    pub grasp: WorldGrasp,
    /// Tool centre (between the pads) at the grasp (m, world).
    pub tcp_m: [f64; 3],
    /// Tool z at the pre-grasp (m).
    pub pregrasp_z_m: f64,
    /// Commanded opening (m): predicted + margin, at most the stroke.
    pub opening_m: f64,
    /// Highest surface in the open fingers' lanes above the table (m; from the depth image).
    pub lane_height_m: f64,
    /// Highest surface under the palm above the table (m).
    pub palm_height_m: f64,
    /// Fingertip height above the table at the grasp (m).
    pub tip_height_m: f64,
    /// The lower of the two pads' highest surfaces above the table on their halves of the
    /// closing line, between the open pads and 2 mm to either side of the pads' width (m; from
    /// the depth image): what the pads can meet as they close.
    pub contact_height_m: f64,
}

impl GraspPlan {
    /// Whether both pads, as planned, close on something: the fingertips are at least
    /// [`AttemptConfig::pad_overlap_m`] below the highest surface on each pad's half of the
    /// closing line. The clearances that keep the fingers off a neighbour in their lanes or the
    /// palm off whatever is under it can raise the tips above the object between them (a pile,
    /// a low object beside a tall one); such a plan would close on air.
    pub fn reaches_contacts(&self, config: &AttemptConfig) -> bool {
        self.tip_height_m + config.pad_overlap_m <= self.contact_height_m
    }
}

/// Plans the tool targets of `grasp` seen in `view`: the commanded opening, the fingertip height
/// (see [`AttemptConfig`]) from the close-up's depth, the pre-grasp height.
pub fn plan_grasp(
    cell: &Cell,
    view: &ObjectView,
    grasp: &WorldGrasp,
    config: &AttemptConfig,
) -> GraspPlan {
    plan_grasp_for(
        cell.robot.gripper().config(),
        cell.table_top_m(),
        view,
        grasp,
        config,
    )
}

/// [`plan_grasp`] for gripper `g` over a table whose top is at `top` (m): what it needs of the
/// cell, so a gripper without an arm ([`crate::grasping::free_grasp`]) plans the same way.
pub fn plan_grasp_for(
    g: &GripperConfig,
    top: f64,
    view: &ObjectView,
    grasp: &WorldGrasp,
    config: &AttemptConfig,
) -> GraspPlan {
    let stroke = f64::from(g.stroke_m);
    let opening = (grasp.opening_m + config.opening_margin_m).clamp(0.0, stroke);
    let thickness = f64::from(g.finger_thickness_m);
    let half_width = 0.5 * f64::from(g.finger_width_m);
    let palm_half_len = f64::from(g.palm_half_length_m());
    let palm_half_width = f64::from(g.palm_half_width_m);
    let finger_len = f64::from(g.finger_length_m);
    let (s, c) = grasp.yaw_rad.sin_cos();
    let [gx, gy, gz] = grasp.position_m;
    // Heights (above the table) of every close-up pixel near the grasp, sorted into the open
    // fingers' lanes (2 mm wider than the pads) and the palm's footprint.
    let k = view.shot.camera.intrinsics;
    let world_from_camera = view.shot.camera.world_from_camera;
    let camera_from_world = world_from_camera.inverse();
    let centre = transform_point(&camera_from_world, grasp.position_m.map(|v| v as f32));
    let reach_m = (palm_half_len.max(0.5 * opening + thickness) + 0.01).hypot(palm_half_width);
    let (mut lane, mut palm, mut tallest) = (0.0f64, 0.0f64, 0.0f64);
    // Highest surface on each pad's half of the closing line (a < 0, a > 0).
    let mut halves = [0.0f64; 2];
    let depth = &view.shot.frame.depth_m;
    let (w, h) = (k.width as i64, k.height as i64);
    for d in depth.iter().filter(|d| d.is_finite() && **d > 0.0) {
        tallest = tallest.max(f64::from(view.crop.table_depth_m - d));
    }
    if let Some([u0, v0]) = k.project(centre) {
        let r_px = (reach_m * f64::from(k.fx) / f64::from(centre[2]).max(0.05)).ceil() as i64 + 2;
        let (u0, v0) = (u0.round() as i64, v0.round() as i64);
        for v in (v0 - r_px).max(0)..=(v0 + r_px).min(h - 1) {
            for u in (u0 - r_px).max(0)..=(u0 + r_px).min(w - 1) {
                let z = depth[(v * w + u) as usize];
                if !(z.is_finite() && z > 0.0) {
                    continue;
                }
                let p = transform_point(&world_from_camera, k.unproject(u as f32, v as f32, z));
                let (dx, dy) = (f64::from(p[0]) - gx, f64::from(p[1]) - gy);
                let a = dx * c + dy * s;
                let b = -dx * s + dy * c;
                let height = f64::from(p[2]) - top;
                if a.abs() >= 0.5 * opening - 0.001
                    && a.abs() <= 0.5 * opening + thickness + 0.002
                    && b.abs() <= half_width + 0.002
                {
                    lane = lane.max(height);
                }
                if a.abs() < 0.5 * opening && b.abs() <= half_width + 0.002 {
                    let half = &mut halves[usize::from(a > 0.0)];
                    *half = half.max(height);
                }
                if a.abs() <= palm_half_len && b.abs() <= palm_half_width {
                    palm = palm.max(height);
                }
            }
        }
    }
    let surface = gz - top;
    let tip = (surface - config.grasp_depth_m)
        .max(config.min_tip_height_m)
        .max(lane + config.lane_clearance_m)
        .max(palm + config.palm_clearance_m - finger_len);
    let tip_from_tcp = f64::from(g.tip_from_tcp_m());
    let pregrasp_tip = config
        .approach_height_m
        .max(tallest + config.approach_clearance_m)
        .max(tip + 0.02);
    GraspPlan {
        grasp: *grasp,
        tcp_m: [gx, gy, top + tip + tip_from_tcp],
        pregrasp_z_m: top + pregrasp_tip + tip_from_tcp,
        opening_m: opening,
        lane_height_m: lane,
        palm_height_m: palm,
        tip_height_m: tip,
        contact_height_m: halves[0].min(halves[1]),
    }
}
