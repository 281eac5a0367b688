//! Recognition constants ([`RecognitionConfig`]), each field's default stated, checked once.

use lgdm_pointcloud::dataset::CameraSpec;
use serde::{Deserialize, Serialize};

use crate::perception::camera::ObjectDrawing;

use crate::recognition::error::RecognitionError;

/// Recognition constants. Defaults are stated per field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecognitionConfig {
    /// The views' camera (default: the dataset's, [`CameraSpec::default`]).
    pub camera: CameraSpec,
    /// Views with more object pixels are subsampled to this many points (default 2048, the
    /// dataset's `max_points_per_view`).
    pub max_points_per_view: usize,
    /// Views of one look, the sequence the first guess comes from (default 5).
    pub look_views: usize,
    /// Views the robot gathers to learn an object it was taught (default 10: a full orbit).
    pub teach_views: usize,
    /// Azimuth step between views (rad; default 36°, the small dataset's turntable step).
    pub view_step_rad: f32,
    /// Views showing fewer of the object's points are skipped (default 30).
    pub min_points: usize,
    /// Below this share of agreeing views the robot says "I don't know this" (default 0.6).
    pub confidence_threshold: f64,
    /// Passes over a lesson's views (default 3).
    pub teach_epochs: usize,
    /// Intrinsic replay after each round (default true).
    pub replay: bool,
    /// Learn every object met, also the ones the robot knew (its own, right, labels; default
    /// false: only the teacher's lessons). More learning in the loop, hence more to forget.
    pub learn_known: bool,
    /// What the views draw (default `mesh`, what the dataset draws).
    pub draw: ObjectDrawing,
}

impl Default for RecognitionConfig {
    fn default() -> Self {
        Self {
            camera: CameraSpec::default(),
            max_points_per_view: 2048,
            look_views: 5,
            teach_views: 10,
            view_step_rad: 36f32.to_radians(),
            min_points: 30,
            confidence_threshold: 0.6,
            teach_epochs: 3,
            replay: true,
            learn_known: false,
            draw: ObjectDrawing::Mesh,
        }
    }
}

impl RecognitionConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RecognitionError> {
        let bad = |field: &'static str, reason: String| {
            Err(RecognitionError::InvalidConfig { field, reason })
        };
        for (field, v) in [
            ("max_points_per_view", self.max_points_per_view),
            ("look_views", self.look_views),
            ("teach_views", self.teach_views),
            ("teach_epochs", self.teach_epochs),
        ] {
            if v == 0 {
                return bad(field, "must be at least 1".into());
            }
        }
        if self.look_views > 1000 || self.teach_views > 1000 || self.teach_epochs > 1000 {
            return bad("look_views", "views and epochs must be at most 1000".into());
        }
        if !self.view_step_rad.is_finite() {
            return bad("view_step_rad", "must be finite".into());
        }
        if !(0.0..=1.0).contains(&self.confidence_threshold) {
            return bad(
                "confidence_threshold",
                format!("{} must be in [0, 1]", self.confidence_threshold),
            );
        }
        let c = &self.camera;
        if !(c.distance_m.is_finite() && c.distance_m > 0.05 && c.distance_m < 10.0) {
            return bad(
                "camera.distance_m",
                format!("{} must be in (0.05, 10) m", c.distance_m),
            );
        }
        if !(c.elevation_rad.is_finite() && c.target_height_m.is_finite()) {
            return bad("camera.elevation_rad", "must be finite".into());
        }
        if !(8..=4096).contains(&c.width) || !(8..=4096).contains(&c.height) {
            return bad("camera.width", "the image must be 8..=4096 px".into());
        }
        if !(c.focal_px.is_finite() && c.focal_px > 0.0) {
            return bad("camera.focal_px", "must be positive".into());
        }
        Ok(())
    }
}
