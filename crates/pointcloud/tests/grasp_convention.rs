//! One grasp convention for Rust and Python: the golden fixture
//! `tests/fixtures/grasp_convention.json` (rectangles → angles → label maps → decoded grasps,
//! with rim pinches, angles near ±90°, overlapping rectangles, the finger-width jaw and
//! Cornell's) is what this crate computes, bit for bit; train_ae's
//! `tests/test_convention.py` checks its own code against the same file. Regenerate it with
//! `LGDM_BLESS=1 cargo test -p lgdm-pointcloud --test grasp_convention` after a deliberate
//! change of convention, and say so in the commit.

use std::path::PathBuf;

use lgdm_pointcloud::grasp::GraspRectangle;
use lgdm_pointcloud::grasp::decode::{
    DEFAULT_JAW_SIDE_FRACTION, GraspDecodeParams, LABEL_CENTRE_FRACTION, WIDTH_SCALE_PX,
    decode_grasps, grasp_angle, grasp_maps,
};
use serde_json::{Value, json};

fn fixture_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/grasp_convention.json")
}

/// θ in degrees counter-clockwise on screen (the convention's angle), opening and jaw in px.
fn rect(cx: f32, cy: f32, theta_deg: f32, opening_px: f32, jaw_px: f32) -> GraspRectangle {
    GraspRectangle::from_center([cx, cy], -theta_deg.to_radians(), opening_px, jaw_px)
}

struct Case {
    name: &'static str,
    size: usize,
    jaw_side_fraction: Option<f32>,
    num_grasps: usize,
    rectangles: Vec<GraspRectangle>,
}

fn cases() -> Vec<Case> {
    let f = DEFAULT_JAW_SIDE_FRACTION;
    let finger = |size: usize| f * size as f32;
    // A bowl's rim seen from above at the cpu input (112 px ≈ 2 mm/px): 5 mm wall + 2 × 4 mm
    // clearance ≈ 6.5 px opening, 10 px jaw, radial, every 45°.
    let ring: Vec<GraspRectangle> = (0..8)
        .map(|k| {
            let a = k as f32 * 45.0 + 10.0;
            let (s, c) = a.to_radians().sin_cos();
            // Screen-ccw angle a: x = cx + r cos a, y = cy − r sin a.
            rect(56.0 + 38.0 * c, 56.0 - 38.0 * s, a, 6.5, finger(112))
        })
        .collect();
    vec![
        Case {
            name: "rim pinch, 5 px opening, finger-width jaw",
            size: 64,
            jaw_side_fraction: Some(f),
            num_grasps: 3,
            rectangles: vec![rect(30.0, 33.0, 20.0, 5.0, finger(64))],
        },
        Case {
            name: "rim ring of a bowl at 112 px",
            size: 112,
            jaw_side_fraction: Some(f),
            num_grasps: 8,
            rectangles: ring,
        },
        Case {
            name: "opening near +90 degrees",
            size: 64,
            jaw_side_fraction: Some(f),
            num_grasps: 1,
            rectangles: vec![rect(31.0, 32.0, 89.0, 30.0, finger(64))],
        },
        Case {
            name: "opening near -90 degrees",
            size: 64,
            jaw_side_fraction: Some(f),
            num_grasps: 1,
            rectangles: vec![rect(32.5, 30.0, -88.5, 30.0, finger(64))],
        },
        Case {
            name: "a +89 and a -89 degree grasp overlapping (smoothing averages to 90)",
            size: 64,
            jaw_side_fraction: Some(f),
            num_grasps: 1,
            rectangles: vec![
                rect(31.0, 31.0, 89.0, 30.0, finger(64)),
                rect(33.0, 31.0, -89.0, 30.0, finger(64)),
            ],
        },
        Case {
            name: "overlapping rectangles, the later wins",
            size: 64,
            jaw_side_fraction: Some(f),
            num_grasps: 2,
            rectangles: vec![
                rect(30.0, 30.0, 0.0, 40.0, 14.0),
                rect(34.0, 32.0, 45.0, 24.0, 8.0),
            ],
        },
        Case {
            name: "three separate grasps, Cornell jaw (opening / 2)",
            size: 96,
            jaw_side_fraction: None,
            num_grasps: 3,
            rectangles: vec![
                rect(20.0, 20.0, 30.0, 36.0, 18.0),
                rect(70.0, 25.0, -60.0, 20.0, 10.0),
                rect(48.0, 75.0, 75.0, 50.0, 25.0),
            ],
        },
        Case {
            name: "no grasp",
            size: 32,
            jaw_side_fraction: Some(f),
            num_grasps: 3,
            rectangles: vec![],
        },
    ]
}

fn compute() -> Value {
    let cases: Vec<Value> = cases()
        .iter()
        .map(|c| {
            let maps = grasp_maps(&c.rectangles, c.size, c.size).unwrap();
            let params = GraspDecodeParams {
                num_grasps: c.num_grasps,
                jaw_side_fraction: c.jaw_side_fraction,
                ..GraspDecodeParams::default()
            };
            let decoded = decode_grasps(maps.view(), &params).unwrap();
            json!({
                "name": c.name,
                "rows": c.size,
                "cols": c.size,
                "jaw_px": c.jaw_side_fraction.map(|f| f * c.size as f32),
                "num_grasps": c.num_grasps,
                "rectangles": c.rectangles.iter().map(|r| r.corners_px).collect::<Vec<_>>(),
                "angles": c.rectangles.iter().map(grasp_angle).collect::<Vec<_>>(),
                "maps": {
                    "quality": maps.quality,
                    "cos2t": maps.cos2t,
                    "sin2t": maps.sin2t,
                    "width": maps.width,
                },
                "decoded": decoded.iter().map(|d| json!({
                    "center_px": d.center_px,
                    "angle": d.angle,
                    "width_px": d.width_px,
                    "jaw_px": d.jaw_px,
                    "quality": d.quality,
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    let p = GraspDecodeParams::default();
    json!({
        "format": "lgdm.grasp-convention.v1",
        "about": "Golden fixture of the grasp convention, written by crates/pointcloud/tests/grasp_convention.rs (LGDM_BLESS=1) and read by python/train_ae/tests/test_convention.py. Angles: radians, counter-clockwise on screen from +x, wrapped to [-pi/2, pi/2). Rectangles: four [x, y] corners, corner 0->1 the opening axis, 1->2 the jaw. Maps: row-major.",
        "convention": {
            "width_scale_px": WIDTH_SCALE_PX,
            "label_centre_fraction": LABEL_CENTRE_FRACTION,
            "quality_threshold": p.quality_threshold,
            "min_distance_px": p.min_distance_px,
            "quality_sigma_px": p.quality_sigma_px,
            "width_sigma_px": p.width_sigma_px,
            "jaw_side_fraction": DEFAULT_JAW_SIDE_FRACTION,
        },
        "cases": cases,
    })
}

#[test]
fn the_golden_fixture_is_what_this_crate_computes() {
    let now = compute();
    let path = fixture_path();
    if std::env::var_os("LGDM_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let text = serde_json::to_string(&now).unwrap() + "\n";
        std::fs::write(&path, text).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (write it with LGDM_BLESS=1 cargo test -p lgdm-pointcloud --test grasp_convention)",
            path.display()
        )
    });
    let stored: Value = serde_json::from_str(&text).unwrap();
    // Same code, same floats: every number is compared exactly as the f32 it was computed as
    // (serde_json's last-digit parsing of f64 text depends on its `float_roundtrip` feature,
    // which other workspace crates switch on).
    if let Some(path) = first_difference(&stored, &now, String::new()) {
        panic!("the grasp convention changed at {path}; see this file's docs");
    }
}

fn first_difference(a: &Value, b: &Value, path: String) -> Option<String> {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64()? as f32, y.as_f64()? as f32);
            (x.to_bits() != y.to_bits()).then(|| format!("{path}: {x} vs {y}"))
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                return Some(format!("{path}: {} vs {} items", x.len(), y.len()));
            }
            x.iter()
                .zip(y)
                .enumerate()
                .find_map(|(i, (u, v))| first_difference(u, v, format!("{path}[{i}]")))
        }
        (Value::Object(x), Value::Object(y)) => {
            if x.len() != y.len() {
                return Some(format!("{path}: keys differ"));
            }
            x.iter().find_map(|(k, u)| match y.get(k) {
                Some(v) => first_difference(u, v, format!("{path}/{k}")),
                None => Some(format!("{path}/{k}: missing")),
            })
        }
        _ => (a != b).then(|| format!("{path}: {a} vs {b}")),
    }
}

/// The fixture exercises what it claims: rims decode back to themselves with the finger-width
/// jaw, the ±89° pair decodes near ±90°, and the empty case has no grasp.
#[test]
fn the_fixture_cases_round_trip() {
    for c in cases() {
        let maps = grasp_maps(&c.rectangles, c.size, c.size).unwrap();
        let params = GraspDecodeParams {
            num_grasps: c.num_grasps,
            jaw_side_fraction: c.jaw_side_fraction,
            ..GraspDecodeParams::default()
        };
        let decoded = decode_grasps(maps.view(), &params).unwrap();
        if c.rectangles.is_empty() {
            assert!(decoded.is_empty(), "{}", c.name);
            continue;
        }
        assert!(!decoded.is_empty(), "{}", c.name);
        if c.name.starts_with("rim") {
            // Every rim pinch comes back within a pixel, its angle within 3°, its jaw the
            // finger width; its opening is under-read (the width map is smoothed with the zeros
            // around a 2-px-wide label) but stays within a factor of two, so the rectangle still
            // overlaps its label by IoU > 0.25.
            assert_eq!(decoded.len(), c.rectangles.len(), "{}", c.name);
            for d in &decoded {
                let truth = c
                    .rectangles
                    .iter()
                    .min_by(|a, b| {
                        let da =
                            (a.center()[0] - d.center_px[0]).hypot(a.center()[1] - d.center_px[1]);
                        let db =
                            (b.center()[0] - d.center_px[0]).hypot(b.center()[1] - d.center_px[1]);
                        da.total_cmp(&db)
                    })
                    .unwrap();
                let dist =
                    (truth.center()[0] - d.center_px[0]).hypot(truth.center()[1] - d.center_px[1]);
                assert!(dist <= 1.0, "{}: centre off by {dist}", c.name);
                let da =
                    lgdm_pointcloud::grasp::decode::angle_difference(d.angle, grasp_angle(truth));
                assert!(
                    da.abs() < 3f32.to_radians(),
                    "{}: angle off by {da}",
                    c.name
                );
                assert!((d.jaw_px - truth.height_px()).abs() < 1e-3, "{}", c.name);
                let ratio = d.width_px / truth.width_px();
                assert!(
                    (0.5..=1.05).contains(&ratio),
                    "{}: opening ratio {ratio}",
                    c.name
                );
            }
        }
        if c.name.contains("+89 and a -89") {
            assert!(
                decoded[0].angle.abs() > 85f32.to_radians(),
                "{}",
                decoded[0].angle
            );
        }
    }
}
