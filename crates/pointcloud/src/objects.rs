//! The procedural object library: ten household-like categories whose instances differ in
//! proportions and details, built deterministically from a seed, with real-object sizes in
//! metres.
//!
//! Look-alike pairs make recognition non-trivial: `bottle`/`vase`, `can`/`glass`,
//! `cereal_box`/`book`, `mug`/`teapot` (both have handles), `bowl`/`glass` (open vessels).
//!
//! ```
//! use lgdm_pointcloud::objects::{procedural_library, CATEGORIES};
//! let objects = procedural_library(&CATEGORIES[..2], 3, 7).unwrap();
//! assert_eq!(objects.len(), 6);
//! assert_eq!(objects[0].name, "mug_01");
//! let (lo, _) = objects[0].mesh.bounds().unwrap();
//! assert!(lo[2].abs() < 1e-6); // resting on the table plane z = 0
//! ```

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::math::derive_seed;
use crate::mesh::Mesh;

/// The procedural categories, in their canonical order.
pub const CATEGORIES: [&str; 10] = [
    "mug",
    "teapot",
    "bowl",
    "bottle",
    "vase",
    "can",
    "glass",
    "cereal_box",
    "book",
    "apple",
];

/// One object of a dataset: its names and its mesh (object frame: z up, resting on z = 0,
/// centred on the z axis).
#[derive(Debug, Clone)]
pub struct ObjectModel {
    /// Instance name, unique in a dataset (`mug_03`).
    pub name: String,
    /// Category name (`mug`).
    pub category: String,
    /// The mesh, metres.
    pub mesh: Mesh,
    /// Its simulated body's mass and friction where they are given (an imported mesh's
    /// `objects.toml`); else the simulator's material rules apply.
    pub physics: crate::sidecar::ObjectPhysics,
    /// The mesh's convex parts where its generator knows them ([`crate::parts`]: the procedural
    /// objects' revolved profiles, tubes and boxes), in the mesh frame; empty for an imported
    /// mesh. A simulator may build its collider from them instead of decomposing the mesh.
    pub parts: Vec<crate::parts::Part>,
}

/// An unknown procedural category name.
#[derive(Debug, Clone, thiserror::Error)]
#[error("unknown procedural category `{0}` (known: {list})", list = CATEGORIES.join(", "))]
pub struct UnknownCategory(pub String);

/// Builds `instances_per_category` instances of each named category, in the given order.
pub fn procedural_library(
    categories: &[&str],
    instances_per_category: usize,
    seed: u64,
) -> Result<Vec<ObjectModel>, UnknownCategory> {
    let mut out = Vec::with_capacity(categories.len() * instances_per_category);
    for &category in categories {
        for instance in 0..instances_per_category {
            let Shape { mesh, parts } = procedural_shape(category, instance, seed)?;
            out.push(ObjectModel {
                name: format!("{category}_{:02}", instance + 1),
                category: category.to_string(),
                mesh,
                physics: Default::default(),
                parts,
            });
        }
    }
    Ok(out)
}

/// Builds instance `instance` of `category` for `seed`.
pub fn procedural_object(
    category: &str,
    instance: usize,
    seed: u64,
) -> Result<Mesh, UnknownCategory> {
    procedural_shape(category, instance, seed).map(|shape| shape.mesh)
}

/// A generated mesh with its convex parts ([`crate::parts`]).
#[derive(Debug, Clone, Default)]
pub struct Shape {
    /// The mesh.
    pub mesh: Mesh,
    /// Its convex parts: their union is the mesh.
    pub parts: Vec<crate::parts::Part>,
}

impl Shape {
    fn lathe(profile: &[[f32; 2]], segments: usize, color: [u8; 3]) -> Shape {
        Shape {
            mesh: Mesh::lathe(profile, segments, color),
            parts: crate::parts::lathe_parts(profile, segments),
        }
    }

    fn lathe_colored(profile: &[[f32; 2]], segments: usize, colors: &[[u8; 3]]) -> Shape {
        Shape {
            mesh: Mesh::lathe_colored(profile, segments, colors),
            parts: crate::parts::lathe_parts(profile, segments),
        }
    }

    fn cuboid(center: [f32; 3], size: [f32; 3], color: [u8; 3]) -> Shape {
        Shape {
            mesh: Mesh::cuboid(center, size, color),
            parts: vec![crate::parts::cuboid_part(center, size)],
        }
    }

    fn append(&mut self, other: Shape) {
        self.mesh.append(&other.mesh);
        self.parts.extend(other.parts);
    }

    fn tube(path: &[[f32; 3]], radius: f32, sides: usize, color: [u8; 3]) -> Shape {
        let radii = vec![radius; path.len()];
        Shape {
            mesh: Mesh::tube(path, radius, sides, color),
            parts: crate::parts::tube_parts(path, &radii, sides),
        }
    }

    fn translate(&mut self, t: [f32; 3]) {
        self.mesh.translate(t);
        for v in self.parts.iter_mut().flatten() {
            *v = crate::math::add(*v, t);
        }
    }
}

/// Builds instance `instance` of `category` for `seed`, with its convex parts.
pub fn procedural_shape(
    category: &str,
    instance: usize,
    seed: u64,
) -> Result<Shape, UnknownCategory> {
    let index = CATEGORIES
        .iter()
        .position(|&c| c == category)
        .ok_or_else(|| UnknownCategory(category.to_string()))?;
    let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(
        seed,
        0x000B_1EC7,
        index as u64,
        instance as u64,
    ));
    let r = &mut rng;
    let mut shape = match category {
        "mug" => mug(r, instance),
        "teapot" => teapot(r, instance),
        "bowl" => bowl(r),
        "bottle" => bottle(r, instance),
        "vase" => vase(r),
        "can" => can(r),
        "glass" => glass(r),
        "cereal_box" => cereal_box(r),
        "book" => book(r),
        "apple" => apple(r),
        _ => unreachable!("category list and match agree"),
    };
    if let Some(t) = table_offset(&shape.mesh) {
        shape.translate(t);
    }
    Ok(shape)
}

/// Centres the mesh's bounding box on the z axis and lowers it onto z = 0.
pub fn rest_on_table(mesh: &mut Mesh) {
    if let Some(t) = table_offset(mesh) {
        mesh.translate(t);
    }
}

/// The translation [`rest_on_table`] applies to `mesh`.
fn table_offset(mesh: &Mesh) -> Option<[f32; 3]> {
    let (lo, hi) = mesh.bounds()?;
    Some([-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0, -lo[2]])
}

const SEGMENTS: usize = 32;

fn u(r: &mut ChaCha8Rng, lo: f32, hi: f32) -> f32 {
    r.random_range(lo..hi)
}

/// A colour near `base`, varied by up to `jitter` per channel.
fn tint(r: &mut ChaCha8Rng, base: [u8; 3], jitter: i32) -> [u8; 3] {
    let mut c = base;
    for v in &mut c {
        let d = r.random_range(-jitter..=jitter);
        *v = (i32::from(*v) + d).clamp(0, 255) as u8;
    }
    c
}

fn pick(r: &mut ChaCha8Rng, palette: &[[u8; 3]]) -> [u8; 3] {
    let i = r.random_range(0..palette.len());
    tint(r, palette[i], 18)
}

const CERAMIC: [[u8; 3]; 6] = [
    [230, 228, 220],
    [40, 70, 140],
    [180, 40, 40],
    [60, 130, 80],
    [230, 190, 60],
    [50, 50, 55],
];

/// Smooth interpolation of radius through `(z, r)` control points (cosine easing).
fn smooth_profile(ctrl: &[[f32; 2]], steps_per_span: usize) -> Vec<[f32; 2]> {
    let mut out = Vec::new();
    for w in ctrl.windows(2) {
        let ([z0, r0], [z1, r1]) = (w[0], w[1]);
        for s in 0..steps_per_span {
            let t = s as f32 / steps_per_span as f32;
            let e = 0.5 - 0.5 * (std::f32::consts::PI * t).cos();
            out.push([r0 + (r1 - r0) * e, z0 + (z1 - z0) * t]);
        }
    }
    if let Some(&[z, r]) = ctrl.last() {
        out.push([r, z]);
    }
    out
}

/// Handle path on the +x side: from `(x0, z_top)` out to `reach` and back to `(x0, z_bot)`.
/// `squareness` ≥ 2 (2 = ellipse, larger = D-shaped).
fn handle_path(x0: f32, z_bot: f32, z_top: f32, reach: f32, squareness: f32) -> Vec<[f32; 3]> {
    let zc = (z_top + z_bot) / 2.0;
    let rz = (z_top - z_bot) / 2.0;
    let n = 16;
    (0..=n)
        .map(|k| {
            let phi = std::f32::consts::FRAC_PI_2 - std::f32::consts::PI * k as f32 / n as f32;
            let (s, c) = phi.sin_cos();
            let e = 2.0 / squareness;
            let cx = c.abs().powf(e);
            let sz = s.signum() * s.abs().powf(e);
            [x0 + reach * cx, 0.0, zc + rz * sz]
        })
        .collect()
}

fn mug(r: &mut ChaCha8Rng, instance: usize) -> Shape {
    let radius = u(r, 0.036, 0.048);
    let height = u(r, 0.08, 0.112);
    let top = radius * u(r, 0.94, 1.14);
    let wall = u(r, 0.004, 0.006);
    let color = pick(r, &CERAMIC);
    let profile = [
        [0.0, 0.0],
        [radius * 0.9, 0.0],
        [radius, 0.007],
        [top, height],
        [top - wall, height],
        [radius - wall, 0.012],
        [0.0, 0.012],
    ];
    let mut mesh = Shape::lathe(&profile, SEGMENTS, color);
    let squareness = if instance.is_multiple_of(2) {
        2.0
    } else {
        u(r, 3.0, 5.0)
    };
    let z_top = height * u(r, 0.72, 0.86);
    let z_bot = height * u(r, 0.18, 0.32);
    let reach = u(r, 0.022, 0.036);
    let thickness = u(r, 0.004, 0.0065);
    let x0 = (radius + top) / 2.0 - 0.004;
    mesh.append(Shape::tube(
        &handle_path(x0, z_bot, z_top, reach, squareness),
        thickness,
        10,
        color,
    ));
    mesh
}

fn teapot(r: &mut ChaCha8Rng, instance: usize) -> Shape {
    let radius = u(r, 0.055, 0.075);
    let rz = radius * u(r, 0.6, 0.85);
    let zc = rz * 0.85;
    let color = pick(r, &CERAMIC);
    let lid = tint(r, color, 25);
    let mut profile = vec![[0.0, 0.0], [radius * 0.55, 0.0]];
    let n = 12;
    let (a0, a1) = (-1.0f32, 1.15f32);
    for k in 0..=n {
        let a = a0 + (a1 - a0) * k as f32 / n as f32;
        profile.push([radius * a.cos(), zc + rz * a.sin()]);
    }
    let z_top = zc + rz * a1.sin();
    let r_open = radius * a1.cos();
    let knob = u(r, 0.008, 0.014);
    profile.extend_from_slice(&[
        [r_open * 0.9, z_top + 0.008],
        [r_open * 0.5, z_top + 0.016],
        [knob, z_top + 0.018],
        [knob * 1.3, z_top + 0.03],
        [0.0, z_top + 0.032],
    ]);
    let body_bands = profile.len() - 1 - 5;
    let mut colors = vec![color; body_bands];
    colors.extend_from_slice(&[lid; 5]);
    let mut mesh = Shape::lathe_colored(&profile, SEGMENTS, &colors);
    // Spout on the -x side.
    let spout_r = u(r, 0.007, 0.012);
    let rise = u(r, 0.6, 1.1);
    let reach = u(r, 0.035, 0.06);
    let spout = [
        [-radius * 0.8, 0.0, zc - 0.2 * rz],
        [-radius - reach * 0.3, 0.0, zc + 0.15 * rz * rise],
        [-radius - reach * 0.7, 0.0, zc + 0.55 * rz * rise],
        [-radius - reach, 0.0, zc + 0.85 * rz * rise],
    ];
    mesh.append(Shape::tube(&spout, spout_r, 10, color));
    let squareness = if instance.is_multiple_of(2) { 2.5 } else { 4.0 };
    let handle = handle_path(
        radius * 0.85,
        zc - 0.45 * rz,
        zc + 0.6 * rz,
        u(r, 0.03, 0.045),
        squareness,
    );
    mesh.append(Shape::tube(&handle, u(r, 0.005, 0.007), 10, color));
    mesh
}

fn bowl(r: &mut ChaCha8Rng) -> Shape {
    let radius = u(r, 0.06, 0.09);
    let height = u(r, 0.045, 0.075);
    let foot = radius * u(r, 0.4, 0.6);
    let foot_h = u(r, 0.005, 0.01);
    let wall = u(r, 0.004, 0.006);
    let k = u(r, 1.6, 3.0);
    let color = pick(r, &CERAMIC);
    let n = 10;
    let curve: Vec<[f32; 2]> = (0..=n)
        .map(|i| {
            let s = i as f32 / n as f32;
            [
                foot + (radius - foot) * (1.0 - (1.0 - s).powf(k)),
                foot_h + (height - foot_h) * s,
            ]
        })
        .collect();
    let mut profile = vec![[0.0, 0.0], [foot, 0.0]];
    profile.extend_from_slice(&curve);
    for p in curve.iter().rev() {
        profile.push([p[0] - wall, p[1].max(foot_h + wall)]);
    }
    profile.push([0.0, foot_h + wall]);
    Shape::lathe(&profile, SEGMENTS, color)
}

const PLASTIC: [[u8; 3]; 6] = [
    [40, 120, 200],
    [30, 150, 60],
    [200, 200, 210],
    [150, 80, 30],
    [220, 60, 60],
    [240, 240, 240],
];

fn bottle(r: &mut ChaCha8Rng, instance: usize) -> Shape {
    let radius = u(r, 0.028, 0.042);
    let height = u(r, 0.2, 0.29);
    let shoulder = height * u(r, 0.55, 0.7);
    let neck_r = u(r, 0.011, 0.016);
    let neck_z = height * u(r, 0.78, 0.86);
    let cap_h = u(r, 0.014, 0.022);
    let body = pick(r, &PLASTIC);
    let label = pick(r, &PLASTIC);
    let cap = pick(r, &PLASTIC);
    let waist = if instance % 3 == 2 {
        u(r, 0.85, 0.93)
    } else {
        1.0
    };
    let mut profile = vec![
        [0.0, 0.0],
        [radius * 0.9, 0.0],
        [radius, 0.008],
        [radius, height * 0.2],
        [radius * waist, shoulder * 0.6],
        [radius, shoulder],
    ];
    let mut colors = vec![body, body, body, label, label];
    let shoulder_pts = smooth_profile(&[[shoulder, radius], [neck_z, neck_r]], 6);
    for p in shoulder_pts.iter().skip(1) {
        profile.push(*p);
        colors.push(body);
    }
    profile.extend_from_slice(&[
        [neck_r, height - cap_h],
        [neck_r + 0.002, height - cap_h],
        [neck_r + 0.002, height],
        [0.0, height],
    ]);
    colors.extend_from_slice(&[body, cap, cap, cap]);
    Shape::lathe_colored(&profile, SEGMENTS, &colors)
}

fn vase(r: &mut ChaCha8Rng) -> Shape {
    let height = u(r, 0.18, 0.28);
    let base = u(r, 0.03, 0.045);
    let belly = u(r, 0.05, 0.072);
    let belly_z = height * u(r, 0.28, 0.5);
    let neck = u(r, 0.018, 0.03);
    let neck_z = height * u(r, 0.75, 0.85);
    let lip = neck * u(r, 1.2, 1.7);
    let wall = 0.004;
    let color = pick(r, &CERAMIC);
    let outer = smooth_profile(
        &[[0.0, base], [belly_z, belly], [neck_z, neck], [height, lip]],
        6,
    );
    let mut profile = vec![[0.0, 0.0]];
    profile.extend_from_slice(&outer);
    for p in outer.iter().rev() {
        profile.push([(p[0] - wall).max(0.002), p[1].max(0.012)]);
    }
    profile.push([0.0, 0.012]);
    Shape::lathe(&profile, SEGMENTS, color)
}

const LABELS: [[u8; 3]; 6] = [
    [200, 20, 30],
    [20, 60, 160],
    [240, 200, 30],
    [30, 140, 60],
    [240, 240, 240],
    [20, 20, 20],
];

fn can(r: &mut ChaCha8Rng) -> Shape {
    let radius = u(r, 0.032, 0.04);
    let height = u(r, 0.1, 0.165);
    let metal = tint(r, [190, 192, 198], 10);
    let label = pick(r, &LABELS);
    let neck = u(r, 0.8, 0.9);
    let profile = [
        [0.0, 0.004],
        [radius * 0.85, 0.0],
        [radius, 0.01],
        [radius, height - 0.014],
        [radius * neck, height - 0.002],
        [radius * neck, height],
        [radius * (neck - 0.04), height],
        [0.0, height - 0.004],
    ];
    let colors = [metal, metal, label, metal, metal, metal, metal];
    Shape::lathe_colored(&profile, SEGMENTS, &colors)
}

fn glass(r: &mut ChaCha8Rng) -> Shape {
    let base = u(r, 0.026, 0.035);
    let top = base * u(r, 1.08, 1.35);
    let height = u(r, 0.09, 0.15);
    let wall = 0.003;
    let bottom = u(r, 0.006, 0.014);
    let color = tint(r, [200, 220, 225], 12);
    let profile = [
        [0.0, 0.0],
        [base, 0.0],
        [top, height],
        [top - wall, height],
        [base - wall, bottom],
        [0.0, bottom],
    ];
    Shape::lathe(&profile, SEGMENTS, color)
}

/// Recolours a cuboid's faces: `[bottom, top, -y, +y, +x, -x]`.
fn paint_cuboid(mesh: &mut Mesh, faces: [[u8; 3]; 6]) {
    for (f, c) in faces.iter().enumerate() {
        mesh.colors[2 * f] = *c;
        mesh.colors[2 * f + 1] = *c;
    }
}

fn cereal_box(r: &mut ChaCha8Rng) -> Shape {
    let w = u(r, 0.18, 0.28);
    let d = u(r, 0.05, 0.08);
    let h = u(r, 0.25, 0.33);
    let front = pick(r, &LABELS);
    let side = tint(r, front, 40);
    let top = tint(r, [220, 210, 190], 15);
    let mut mesh = Shape::cuboid([0.0, 0.0, h / 2.0], [w, d, h], front);
    paint_cuboid(&mut mesh.mesh, [top, top, front, front, side, side]);
    // A printed panel on the front (slightly proud of the surface).
    let panel = pick(r, &LABELS);
    let pw = w * u(r, 0.4, 0.7);
    let ph = h * u(r, 0.25, 0.45);
    let pz = h * u(r, 0.35, 0.6);
    mesh.append(Shape::cuboid(
        [0.0, -d / 2.0 - 0.0005, pz],
        [pw, 0.001, ph],
        panel,
    ));
    mesh
}

fn book(r: &mut ChaCha8Rng) -> Shape {
    let w = u(r, 0.14, 0.23);
    let d = u(r, 0.015, 0.05);
    let h = u(r, 0.19, 0.27);
    let cover = pick(r, &LABELS);
    let pages = tint(r, [235, 230, 210], 8);
    let c = 0.0025;
    let inset = 0.004;
    let mut mesh = Shape::default();
    // Front and back covers, spine on the -x side, page block inset.
    mesh.append(Shape::cuboid(
        [0.0, -d / 2.0 + c / 2.0, h / 2.0],
        [w, c, h],
        cover,
    ));
    mesh.append(Shape::cuboid(
        [0.0, d / 2.0 - c / 2.0, h / 2.0],
        [w, c, h],
        cover,
    ));
    mesh.append(Shape::cuboid(
        [-w / 2.0 + c / 2.0, 0.0, h / 2.0],
        [c, d, h],
        cover,
    ));
    mesh.append(Shape::cuboid(
        [inset / -2.0, 0.0, h / 2.0],
        [w - inset, d - 2.0 * c, h - 2.0 * inset],
        pages,
    ));
    mesh
}

fn apple(r: &mut ChaCha8Rng) -> Shape {
    let radius = u(r, 0.035, 0.046);
    let height = radius * u(r, 1.6, 2.1);
    let top_heavy = u(r, 0.02, 0.16);
    let dimple_top = u(r, 0.006, 0.012);
    let dimple_bottom = u(r, 0.003, 0.008);
    let skin = pick(
        r,
        &[[190, 30, 30], [120, 180, 50], [220, 190, 50], [160, 40, 40]],
    );
    let n = 16;
    let mut profile = vec![[0.0, dimple_bottom]];
    for k in 1..n {
        let a = -std::f32::consts::FRAC_PI_2 + std::f32::consts::PI * k as f32 / n as f32;
        let rr = radius * a.cos() * (1.0 + top_heavy * a.sin());
        profile.push([rr, height / 2.0 * (1.0 + a.sin())]);
    }
    profile.push([0.0, height - dimple_top]);
    let mut mesh = Shape::lathe(&profile, SEGMENTS, skin);
    let lean = u(r, -0.004, 0.004);
    let stem = [
        [0.0, 0.0, height - dimple_top - 0.002],
        [lean, 0.0, height + 0.004],
        [lean * 2.0, 0.0, height + 0.012],
    ];
    mesh.append(Shape::tube(&stem, 0.0018, 6, [90, 60, 30]));
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_category_builds_at_household_size() {
        let objects = procedural_library(&CATEGORIES, 5, 1).unwrap();
        assert_eq!(objects.len(), 50);
        for o in &objects {
            let (lo, hi) = o.mesh.bounds().unwrap();
            let size = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
            assert!(lo[2].abs() < 1e-6, "{} not on table", o.name);
            assert!(
                size.iter().all(|&s| s > 0.01 && s < 0.4),
                "{}: size {size:?}",
                o.name
            );
            assert!(o.mesh.vertices.iter().flatten().all(|v| v.is_finite()));
            assert_eq!(o.mesh.colors.len(), o.mesh.triangles.len());
        }
    }

    #[test]
    fn instances_differ_and_seed_is_deterministic() {
        let a = procedural_object("bottle", 0, 3).unwrap();
        let b = procedural_object("bottle", 1, 3).unwrap();
        let a2 = procedural_object("bottle", 0, 3).unwrap();
        assert_eq!(a, a2);
        assert_ne!(a.vertices, b.vertices);
        assert!(procedural_object("spaceship", 0, 3).is_err());
    }
}
