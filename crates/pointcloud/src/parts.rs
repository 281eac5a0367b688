//! Convex parts of the generated meshes, exact where a voxel decomposition is not: the
//! procedural objects are built from surfaces of revolution ([`Mesh::lathe`]), tubes
//! ([`Mesh::tapered_tube`]) and boxes ([`Mesh::cuboid`]), and each of these splits into convex
//! pieces whose union is the mesh. A simulator can use them as a collider that keeps a vase's
//! neck and a glass's 3 mm wall open, where VHACD at its default resolution fills the neck and a
//! finer one splits the wall into slivers (`docs/experiments/closeup-draws-mesh.md`).
//!
//! A lathe's closed profile (a polygon in the `(r, z)` half-plane) is cut into convex polygons
//! (ear clipping, then Hertel–Mehlhorn merging). A polygon whose edge on the axis spans its whole
//! height revolves into one convex solid; any other (a wall) gives one convex part per segment
//! of the lathe: its vertices at the segment's two angles. Both are exact for the polygonal
//! surface the lathe draws (its facets are chords between the segment angles).
//!
//! ```
//! use lgdm_pointcloud::parts::lathe_parts;
//! // A glass: base disc and a 3 mm wall.
//! let profile = [[0.0, 0.0], [0.03, 0.0], [0.035, 0.1], [0.032, 0.1], [0.027, 0.01], [0.0, 0.01]];
//! let parts = lathe_parts(&profile, 32);
//! assert_eq!(parts.len(), 1 + 32); // the base revolved whole, the wall in 32 pieces
//! ```

use crate::mesh::tube_rings;

/// A convex part: its points (the part is their hull), metres, in the mesh frame.
pub type Part = Vec<[f32; 3]>;

/// Radii below this are on the axis (m).
const AXIS_EPS: f32 = 1e-6;

/// The convex parts of `Mesh::lathe(profile, segments, _)`: see the module docs. A profile of
/// fewer than three distinct points gives none.
pub fn lathe_parts(profile: &[[f32; 2]], segments: usize) -> Vec<Part> {
    let segments = segments.max(3);
    let polygon = clean_polygon(profile);
    if polygon.len() < 3 {
        return Vec::new();
    }
    let angle = |j: usize| {
        let a = std::f32::consts::TAU * j as f32 / segments as f32;
        (a.cos(), a.sin())
    };
    let at = |[r, z]: [f32; 2], (c, s): (f32, f32)| [r * c, r * s, z];
    let mut parts = Vec::new();
    for piece in convex_pieces(&polygon) {
        let pts: Vec<[f32; 2]> = piece.iter().map(|&i| polygon[i]).collect();
        let (z_lo, z_hi) = pts
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[1]), hi.max(p[1]))
            });
        let on_axis = |z: f32| {
            pts.iter()
                .any(|p| p[0] <= AXIS_EPS && (p[1] - z).abs() <= 1e-7)
        };
        if on_axis(z_lo) && on_axis(z_hi) {
            // The piece's inner side is the axis over its whole height: it revolves into one
            // convex solid (its slices are regular polygons scaled by a concave radius).
            let mut part = Vec::new();
            for &p in &pts {
                if p[0] <= AXIS_EPS {
                    part.push([0.0, 0.0, p[1]]);
                } else {
                    part.extend((0..segments).map(|j| at(p, angle(j))));
                }
            }
            parts.push(part);
        } else {
            for j in 0..segments {
                let (a, b) = (angle(j), angle(j + 1));
                let mut part = Vec::with_capacity(2 * pts.len());
                for &p in &pts {
                    part.push(at(p, a));
                    if p[0] > AXIS_EPS {
                        part.push(at(p, b));
                    }
                }
                parts.push(part);
            }
        }
    }
    parts
}

/// The convex parts of `Mesh::tapered_tube(path, radii, sides, _)`: the hull of each pair of
/// consecutive rings. None where the tube is empty.
pub fn tube_parts(path: &[[f32; 3]], radii: &[f32], sides: usize) -> Vec<Part> {
    let Some(rings) = tube_rings(path, radii, sides) else {
        return Vec::new();
    };
    rings
        .windows(2)
        .map(|w| w[0].iter().chain(&w[1]).copied().collect())
        .collect()
}

/// The one convex part of `Mesh::cuboid(center, size, _)`: its eight corners.
pub fn cuboid_part(center: [f32; 3], size: [f32; 3]) -> Part {
    let h = size.map(|s| s / 2.0);
    (0..8)
        .map(|k| {
            let sign = |bit: usize| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            [
                center[0] + sign(0) * h[0],
                center[1] + sign(1) * h[1],
                center[2] + sign(2) * h[2],
            ]
        })
        .collect()
}

/// The profile as a simple polygon, counter-clockwise in `(r, z)`, without repeated or
/// collinear points (the closing edge runs from its last point to its first, on the axis for a
/// closed solid).
fn clean_polygon(profile: &[[f32; 2]]) -> Vec<[f32; 2]> {
    let mut pts: Vec<[f32; 2]> = Vec::with_capacity(profile.len());
    for &p in profile {
        let p = [p[0].max(0.0), p[1]];
        if pts.last().is_none_or(|q: &[f32; 2]| dist2(*q, p) > 1e-14) {
            pts.push(p);
        }
    }
    while pts.len() > 1 && dist2(pts[0], pts[pts.len() - 1]) <= 1e-14 {
        pts.pop();
    }
    if signed_area(&pts) < 0.0 {
        pts.reverse();
    }
    // Drop collinear points until none is left.
    loop {
        let n = pts.len();
        if n < 3 {
            return pts;
        }
        let Some(i) =
            (0..n).find(|&i| cross2(pts[(i + n - 1) % n], pts[i], pts[(i + 1) % n]).abs() < 1e-12)
        else {
            return pts;
        };
        pts.remove(i);
    }
}

/// Convex pieces of a counter-clockwise simple polygon (vertex indices, each piece
/// counter-clockwise): ear clipping, then merging two pieces across a diagonal while the union
/// stays convex (Hertel–Mehlhorn: at most four times the fewest pieces).
fn convex_pieces(poly: &[[f32; 2]]) -> Vec<Vec<usize>> {
    let mut pieces: Vec<Vec<usize>> = ear_clip(poly).into_iter().map(|t| t.to_vec()).collect();
    loop {
        let mut merged = false;
        'search: for a in 0..pieces.len() {
            for b in a + 1..pieces.len() {
                if let Some(union) = merge(&pieces[a], &pieces[b])
                    && is_convex(poly, &union)
                {
                    pieces[a] = union;
                    pieces.swap_remove(b);
                    merged = true;
                    break 'search;
                }
            }
        }
        if !merged {
            return pieces;
        }
    }
}

/// The union of two counter-clockwise pieces sharing an edge (`u → v` in `a`, `v → u` in `b`).
fn merge(a: &[usize], b: &[usize]) -> Option<Vec<usize>> {
    let (na, nb) = (a.len(), b.len());
    for i in 0..na {
        let (u, v) = (a[i], a[(i + 1) % na]);
        if let Some(j) = (0..nb).find(|&j| b[j] == v && b[(j + 1) % nb] == u) {
            // a from v round to u, then b from u round to v (without repeating u, v).
            let mut out: Vec<usize> = (0..na).map(|k| a[(i + 1 + k) % na]).collect();
            out.extend((2..nb).map(|k| b[(j + k) % nb]));
            return Some(out);
        }
    }
    None
}

fn is_convex(poly: &[[f32; 2]], piece: &[usize]) -> bool {
    let n = piece.len();
    (0..n).all(|i| {
        cross2(
            poly[piece[(i + n - 1) % n]],
            poly[piece[i]],
            poly[piece[(i + 1) % n]],
        ) >= -1e-12
    })
}

/// Triangles of a counter-clockwise simple polygon, by ear clipping.
fn ear_clip(poly: &[[f32; 2]]) -> Vec<[usize; 3]> {
    let mut idx: Vec<usize> = (0..poly.len()).collect();
    let mut out = Vec::with_capacity(poly.len().saturating_sub(2));
    while idx.len() > 3 {
        let n = idx.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (idx[(i + n - 1) % n], idx[i], idx[(i + 1) % n]);
            cross2(poly[a], poly[b], poly[c]) > 0.0
                && idx
                    .iter()
                    .filter(|&&k| k != a && k != b && k != c)
                    .all(|&k| !in_triangle(poly[k], poly[a], poly[b], poly[c]))
        });
        // A polygon with no ear is not simple: take the flattest corner so the loop ends.
        let i = ear.unwrap_or(0);
        out.push([idx[(i + n - 1) % n], idx[i], idx[(i + 1) % n]]);
        idx.remove(i);
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    out
}

fn in_triangle(p: [f32; 2], a: [f32; 2], b: [f32; 2], c: [f32; 2]) -> bool {
    cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0
}

/// `(b - a) × (c - b)`: positive where `a, b, c` turn left.
fn cross2(a: [f32; 2], b: [f32; 2], c: [f32; 2]) -> f32 {
    (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
}

fn signed_area(p: &[[f32; 2]]) -> f32 {
    let n = p.len();
    (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f32>()
        / 2.0
}

fn dist2(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the area of a piece (indices into `poly`).
    fn area(poly: &[[f32; 2]], piece: &[usize]) -> f32 {
        let pts: Vec<[f32; 2]> = piece.iter().map(|&i| poly[i]).collect();
        signed_area(&pts)
    }

    #[test]
    fn pieces_of_a_vessel_profile_are_convex_and_cover_it() {
        // A bowl-like profile: up the outside, down the inside.
        let profile = [
            [0.0, 0.0],
            [0.04, 0.0],
            [0.06, 0.02],
            [0.07, 0.05],
            [0.065, 0.05],
            [0.055, 0.022],
            [0.036, 0.005],
            [0.0, 0.005],
        ];
        let poly = clean_polygon(&profile);
        assert!(signed_area(&poly) > 0.0);
        let pieces = convex_pieces(&poly);
        let total: f32 = pieces.iter().map(|p| area(&poly, p)).sum();
        assert!((total - signed_area(&poly)).abs() < 1e-9, "{total}");
        for piece in &pieces {
            assert!(is_convex(&poly, piece), "{piece:?}");
        }
        assert!(pieces.len() < poly.len() - 2, "merged: {}", pieces.len());
    }

    #[test]
    fn a_solid_profile_touching_the_axis_revolves_into_one_part() {
        // A can: the profile is convex and its inner side is the axis.
        let profile = [[0.0, 0.0], [0.04, 0.0], [0.04, 0.12], [0.0, 0.12]];
        let parts = lathe_parts(&profile, 16);
        assert_eq!(parts.len(), 1);
        assert_eq!(parts[0].len(), 2 + 2 * 16);
    }

    #[test]
    fn a_tube_has_one_part_per_segment_and_a_cuboid_eight_corners() {
        let path = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.05], [0.02, 0.0, 0.09]];
        let parts = tube_parts(&path, &[0.01; 3], 10);
        assert_eq!(parts.len(), 2);
        assert!(parts.iter().all(|p| p.len() == 20));
        assert!(tube_parts(&path[..1], &[0.01], 10).is_empty());
        let c = cuboid_part([1.0, 2.0, 3.0], [2.0, 4.0, 6.0]);
        assert_eq!(c.len(), 8);
        assert!(c.contains(&[0.0, 0.0, 0.0]) && c.contains(&[2.0, 4.0, 6.0]));
    }
}
