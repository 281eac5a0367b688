//! Triangle meshes in metres with one colour per triangle, the primitives the procedural
//! object library is built from (surfaces of revolution, boxes, swept tubes), and ray casting.
//!
//! Object meshes use the object frame: z up, resting on the plane z = 0, centred on the z axis.
//!
//! ```
//! use lgdm_pointcloud::mesh::Mesh;
//! let cup = Mesh::lathe(&[[0.0, 0.0], [0.04, 0.0], [0.04, 0.1], [0.0, 0.1]], 24, [200, 30, 30]);
//! let (lo, hi) = cup.bounds().unwrap();
//! assert!((hi[2] - 0.1).abs() < 1e-6 && lo[2].abs() < 1e-6);
//! ```

use crate::math::{Pose, add, cross, dot, norm, normalize, scale, sub, transform_point};

/// A triangle mesh: vertices in metres, counter-clockwise (outward) triangles, a colour each.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    /// Vertex positions in metres.
    pub vertices: Vec<[f32; 3]>,
    /// Vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// One 8-bit RGB colour per triangle.
    pub colors: Vec<[u8; 3]>,
}

/// The first intersection of a ray with a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction, metres.
    pub t: f32,
    /// Index of the triangle hit.
    pub triangle: usize,
    /// Unit geometric normal of that triangle, as wound (outward for well-formed meshes).
    pub normal: [f32; 3],
}

impl Mesh {
    /// An empty mesh.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Adds a triangle by vertex positions.
    pub fn push_triangle(&mut self, a: [f32; 3], b: [f32; 3], c: [f32; 3], color: [u8; 3]) {
        let i = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&[a, b, c]);
        self.triangles.push([i, i + 1, i + 2]);
        self.colors.push(color);
    }

    /// Appends another mesh.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
        self.colors.extend_from_slice(&other.colors);
    }

    /// Returns the mesh with `pose` applied to every vertex.
    pub fn transformed(&self, pose: &Pose) -> Mesh {
        Mesh {
            vertices: self
                .vertices
                .iter()
                .map(|&v| transform_point(pose, v))
                .collect(),
            triangles: self.triangles.clone(),
            colors: self.colors.clone(),
        }
    }

    /// Scales each axis independently about the origin (keeps winding when all factors are > 0).
    pub fn scale_xyz(&mut self, s: [f32; 3]) {
        for v in &mut self.vertices {
            for k in 0..3 {
                v[k] *= s[k];
            }
        }
    }

    /// Moves every vertex by `t`.
    pub fn translate(&mut self, t: [f32; 3]) {
        for v in &mut self.vertices {
            *v = add(*v, t);
        }
    }

    /// Axis-aligned bounds `(min, max)`, `None` when there are no vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        crate::cloud::bounds(&self.vertices)
    }

    /// Unit normal of triangle `i` (zero for a degenerate triangle).
    pub fn face_normal(&self, i: usize) -> [f32; 3] {
        let [a, b, c] = self.triangle_vertices(i);
        normalize(cross(sub(b, a), sub(c, a)))
    }

    /// The three vertex positions of triangle `i`.
    #[inline]
    pub fn triangle_vertices(&self, i: usize) -> [[f32; 3]; 3] {
        let t = self.triangles[i];
        [
            self.vertices[t[0] as usize],
            self.vertices[t[1] as usize],
            self.vertices[t[2] as usize],
        ]
    }

    /// Total surface area in m².
    pub fn area(&self) -> f32 {
        (0..self.len())
            .map(|i| {
                let [a, b, c] = self.triangle_vertices(i);
                0.5 * norm(cross(sub(b, a), sub(c, a)))
            })
            .sum()
    }

    /// The mesh simplified by vertex clustering on a grid of cubes `cell_m` wide (anchored at the
    /// mesh's lower bounds): the vertices of one cube merge into their mean, triangles whose
    /// corners fall into fewer than three cubes are dropped, and so are repeats of a triangle
    /// (the same three cubes; the first is kept, with its colour). Every vertex moves by less
    /// than a cube's diagonal, so the result's hull is within `√3·cell_m` of the mesh's.
    /// Deterministic: clusters are numbered in the order of their first vertex. A `cell_m` that
    /// is not positive and finite returns a copy.
    ///
    /// ```
    /// use lgdm_pointcloud::mesh::Mesh;
    /// let fine = Mesh::lathe(&[[0.0, 0.0], [0.04, 0.0], [0.04, 0.1], [0.0, 0.1]], 720, [9; 3]);
    /// let coarse = fine.clustered(0.002);
    /// assert!(coarse.len() < fine.len() / 4);
    /// let (lo, hi) = coarse.bounds().unwrap();
    /// assert!(hi[2] > 0.098 && lo[2] < 0.002 && hi[0] > 0.038);
    /// ```
    pub fn clustered(&self, cell_m: f32) -> Mesh {
        let Some((lo, _)) = self.bounds() else {
            return self.clone();
        };
        if !(cell_m.is_finite() && cell_m > 0.0) {
            return self.clone();
        }
        let mut cluster_of_cell: std::collections::HashMap<[i64; 3], u32> =
            std::collections::HashMap::new();
        let mut sums: Vec<[f64; 3]> = Vec::new();
        let mut counts: Vec<u32> = Vec::new();
        let cluster: Vec<u32> = self
            .vertices
            .iter()
            .map(|v| {
                let cell = [0, 1, 2].map(|k| ((v[k] - lo[k]) / cell_m).floor() as i64);
                let id = *cluster_of_cell.entry(cell).or_insert_with(|| {
                    sums.push([0.0; 3]);
                    counts.push(0);
                    (sums.len() - 1) as u32
                });
                let sum = &mut sums[id as usize];
                for k in 0..3 {
                    sum[k] += f64::from(v[k]);
                }
                counts[id as usize] += 1;
                id
            })
            .collect();
        let mut seen: std::collections::HashSet<[u32; 3]> = std::collections::HashSet::new();
        let mut out = Mesh {
            vertices: sums
                .iter()
                .zip(&counts)
                .map(|(s, &n)| s.map(|c| (c / f64::from(n)) as f32))
                .collect(),
            ..Mesh::default()
        };
        for (t, color) in self.triangles.iter().zip(&self.colors) {
            let ids = t.map(|i| cluster[i as usize]);
            if ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2] {
                continue;
            }
            let mut key = ids;
            key.sort_unstable();
            if seen.insert(key) {
                out.triangles.push(ids);
                out.colors.push(*color);
            }
        }
        out
    }

    /// First hit of the ray `origin + t·dir` (dir normalised here) with `t` in `(0, t_max]`,
    /// Möller–Trumbore on every triangle (both faces count).
    pub fn raycast(&self, origin: [f32; 3], dir: [f32; 3], t_max: f32) -> Option<RayHit> {
        let dir = normalize(dir);
        let mut best: Option<RayHit> = None;
        let mut t_best = t_max;
        for i in 0..self.len() {
            let [a, b, c] = self.triangle_vertices(i);
            let e1 = sub(b, a);
            let e2 = sub(c, a);
            let p = cross(dir, e2);
            let det = dot(e1, p);
            if det.abs() < 1e-12 {
                continue;
            }
            let inv = 1.0 / det;
            let s = sub(origin, a);
            let u = dot(s, p) * inv;
            if !(0.0..=1.0).contains(&u) {
                continue;
            }
            let q = cross(s, e1);
            let v = dot(dir, q) * inv;
            if v < 0.0 || u + v > 1.0 {
                continue;
            }
            let t = dot(e2, q) * inv;
            if t > 1e-6 && t <= t_best {
                t_best = t;
                best = Some(RayHit {
                    t,
                    triangle: i,
                    normal: normalize(cross(e1, e2)),
                });
            }
        }
        best
    }

    /// Surface of revolution about the z axis. `profile` holds `[radius, z]` pairs in metres;
    /// walking the profile upward along the outside gives outward normals. A profile point with
    /// radius 0 closes the surface there (triangle fan), so a profile from `[0, z0]` out, up and
    /// back to `[0, z1]` gives a closed solid.
    pub fn lathe(profile: &[[f32; 2]], segments: usize, color: [u8; 3]) -> Mesh {
        Self::lathe_colored(
            profile,
            segments,
            &vec![color; profile.len().saturating_sub(1)],
        )
    }

    /// Like [`Mesh::lathe`] with one colour per profile segment (`colors.len() == profile.len() - 1`).
    pub fn lathe_colored(profile: &[[f32; 2]], segments: usize, colors: &[[u8; 3]]) -> Mesh {
        let segments = segments.max(3);
        let mut mesh = Mesh::new();
        let ring = |r: f32, z: f32, j: usize| {
            let a = std::f32::consts::TAU * j as f32 / segments as f32;
            [r * a.cos(), r * a.sin(), z]
        };
        for (i, w) in profile.windows(2).enumerate() {
            let color = colors.get(i).copied().unwrap_or([128, 128, 128]);
            let ([r0, z0], [r1, z1]) = (w[0], w[1]);
            for j in 0..segments {
                let a = ring(r0, z0, j);
                let b = ring(r1, z1, j);
                let c = ring(r1, z1, j + 1);
                let d = ring(r0, z0, j + 1);
                if r0 > 0.0 {
                    mesh.push_triangle(a, d, c, color);
                }
                if r1 > 0.0 {
                    mesh.push_triangle(a, c, b, color);
                }
            }
        }
        mesh
    }

    /// The mesh as Wavefront OBJ text: its vertices as given (file units) and its triangles,
    /// without colours — what `--meshes` reads back (`lgdm_pointcloud::import`).
    ///
    /// ```
    /// use lgdm_pointcloud::mesh::Mesh;
    /// let obj = Mesh::cuboid([0.0; 3], [1.0; 3], [9, 9, 9]).to_obj();
    /// assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), 8);
    /// assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 12);
    /// ```
    pub fn to_obj(&self) -> String {
        let mut s = String::from("o mesh\n");
        for v in &self.vertices {
            s += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        for t in &self.triangles {
            s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// An axis-aligned box centred at `center` with edge lengths `size` (metres).
    pub fn cuboid(center: [f32; 3], size: [f32; 3], color: [u8; 3]) -> Mesh {
        let h = scale(size, 0.5);
        let v = |sx: f32, sy: f32, sz: f32| add(center, [sx * h[0], sy * h[1], sz * h[2]]);
        let corners = [
            v(-1.0, -1.0, -1.0),
            v(1.0, -1.0, -1.0),
            v(1.0, 1.0, -1.0),
            v(-1.0, 1.0, -1.0),
            v(-1.0, -1.0, 1.0),
            v(1.0, -1.0, 1.0),
            v(1.0, 1.0, 1.0),
            v(-1.0, 1.0, 1.0),
        ];
        // Outward faces as quads (counter-clockwise from outside).
        let quads = [
            [0, 3, 2, 1], // bottom
            [4, 5, 6, 7], // top
            [0, 1, 5, 4], // -y
            [2, 3, 7, 6], // +y
            [1, 2, 6, 5], // +x
            [3, 0, 4, 7], // -x
        ];
        let mut mesh = Mesh::new();
        mesh.vertices.extend_from_slice(&corners);
        for q in quads {
            mesh.triangles.push([q[0], q[1], q[2]]);
            mesh.triangles.push([q[0], q[2], q[3]]);
            mesh.colors.push(color);
            mesh.colors.push(color);
        }
        mesh
    }

    /// A tube of circular cross-section swept along a polyline `path` (metres), with flat end
    /// caps. Used for handles and spouts.
    pub fn tube(path: &[[f32; 3]], radius: f32, sides: usize, color: [u8; 3]) -> Mesh {
        Mesh::tapered_tube(path, &vec![radius; path.len()], sides, color)
    }

    /// A tube like [`Mesh::tube`] whose radius at `path[i]` is `radii[i]` (a stick that
    /// thickens or thins). Empty when `path` has fewer than two points or `radii` another
    /// length.
    pub fn tapered_tube(path: &[[f32; 3]], radii: &[f32], sides: usize, color: [u8; 3]) -> Mesh {
        let mut mesh = Mesh::new();
        let Some(rings) = tube_rings(path, radii, sides) else {
            return mesh;
        };
        let (n, sides) = (rings.len(), rings[0].len());
        for i in 0..n - 1 {
            for j in 0..sides {
                let k = (j + 1) % sides;
                let (a, b, c, d) = (rings[i][j], rings[i][k], rings[i + 1][k], rings[i + 1][j]);
                mesh.push_triangle(a, b, c, color);
                mesh.push_triangle(a, c, d, color);
            }
        }
        for (ring, center, flip) in [
            (&rings[0], path[0], true),
            (&rings[n - 1], path[n - 1], false),
        ] {
            for j in 0..sides {
                let k = (j + 1) % sides;
                if flip {
                    mesh.push_triangle(center, ring[k], ring[j], color);
                } else {
                    mesh.push_triangle(center, ring[j], ring[k], color);
                }
            }
        }
        mesh
    }
}

/// The rings of [`Mesh::tapered_tube`]: `sides` points (at least 3) around each point of `path`
/// in a parallel-transported frame; `None` when `path` has fewer than two points or `radii`
/// another length. Its convex parts ([`crate::parts::tube_parts`]) are built from the same rings.
pub(crate) fn tube_rings(
    path: &[[f32; 3]],
    radii: &[f32],
    sides: usize,
) -> Option<Vec<Vec<[f32; 3]>>> {
    if path.len() < 2 || radii.len() != path.len() {
        return None;
    }
    let sides = sides.max(3);
    // Tangents and a parallel-transported normal frame.
    let n = path.len();
    let tangent = |i: usize| {
        let a = path[i.saturating_sub(1)];
        let b = path[(i + 1).min(n - 1)];
        normalize(sub(b, a))
    };
    let t0 = tangent(0);
    let helper = if t0[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let mut u = normalize(cross(t0, helper));
    let mut rings: Vec<Vec<[f32; 3]>> = Vec::with_capacity(n);
    for (i, &centre) in path.iter().enumerate() {
        let t = tangent(i);
        // Remove the tangential component to transport the frame.
        u = normalize(sub(u, scale(t, dot(u, t))));
        let w = cross(t, u);
        let ring = (0..sides)
            .map(|j| {
                let a = std::f32::consts::TAU * j as f32 / sides as f32;
                add(
                    centre,
                    add(scale(u, radii[i] * a.cos()), scale(w, radii[i] * a.sin())),
                )
            })
            .collect();
        rings.push(ring);
    }
    Some(rings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lathe_normals_point_outward() {
        let m = Mesh::lathe(
            &[[0.0, 0.0], [0.05, 0.0], [0.05, 0.1], [0.0, 0.1]],
            16,
            [1, 2, 3],
        );
        for i in 0..m.len() {
            let [a, b, c] = m.triangle_vertices(i);
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            let outward = sub(centre, [0.0, 0.0, 0.05]);
            assert!(
                dot(m.face_normal(i), outward) > 0.0,
                "triangle {i} faces inward"
            );
        }
    }

    #[test]
    fn cuboid_normals_point_outward_and_area() {
        let m = Mesh::cuboid([0.0; 3], [0.1, 0.2, 0.3], [0; 3]);
        for i in 0..m.len() {
            let [a, b, c] = m.triangle_vertices(i);
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            assert!(dot(m.face_normal(i), centre) > 0.0);
        }
        let area = 2.0 * (0.1 * 0.2 + 0.1 * 0.3 + 0.2 * 0.3);
        assert!((m.area() - area).abs() < 1e-5);
    }

    #[test]
    fn raycast_hits_box_face() {
        let m = Mesh::cuboid([0.0; 3], [0.2, 0.2, 0.2], [0; 3]);
        let hit = m
            .raycast([1.0, 0.01, 0.02], [-1.0, 0.0, 0.0], 10.0)
            .unwrap();
        assert!((hit.t - 0.9).abs() < 1e-5);
        assert!((hit.normal[0] - 1.0).abs() < 1e-5);
        assert!(m.raycast([1.0, 0.5, 0.0], [-1.0, 0.0, 0.0], 10.0).is_none());
    }

    #[test]
    fn tube_normals_point_outward() {
        let path = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.05], [0.0, 0.0, 0.1]];
        let m = Mesh::tube(&path, 0.01, 12, [0; 3]);
        for i in 0..m.len() {
            let [a, b, c] = m.triangle_vertices(i);
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            assert!(dot(m.face_normal(i), sub(centre, [0.0, 0.0, 0.05])) > 0.0);
        }
    }
}
