//! Convex hulls as the physics' colliders, with their big flat faces thinned: every hull a
//! [`crate::world::World`] builds — a single hull or each part of a decomposition
//! ([`crate::shapes`]) — has faces of more than
//! [`crate::world::WorldConfig::max_face_vertices`] vertices thinned by farthest-point sampling:
//! an upright can whose base is a 32-gon otherwise rocks until it topples. Pure geometry; the
//! world and the shapes both build on it.

use rapier3d::math::Vector;
use rapier3d::prelude::SharedShape;

/// The convex hull of `points` with faces of more than `max_face` vertices thinned (up to three
/// rounds; a round whose hull cannot be built keeps the previous one); `None` when the points
/// have no hull. Every collider [`crate::world::World`] builds goes through here (see
/// [`crate::world::WorldConfig::max_face_vertices`] for why).
pub(crate) fn thinned_hull(points: &[Vector], max_face: usize) -> Option<SharedShape> {
    let mut shape = SharedShape::convex_hull(points)?;
    for _ in 0..3 {
        let Some(kept) = shape
            .as_convex_polyhedron()
            .and_then(|h| thin_big_faces(h, max_face))
        else {
            break;
        };
        match SharedShape::convex_hull(&kept) {
            Some(thinner) => shape = thinner,
            None => break,
        }
    }
    Some(shape)
}

/// The hull's points without the surplus vertices of faces that have more than `max_face`:
/// `None` when no face is that big. The vertices a big face keeps are spread by farthest-point
/// sampling from its first vertex (deterministic).
fn thin_big_faces(
    hull: &rapier3d::parry::shape::ConvexPolyhedron,
    max_face: usize,
) -> Option<Vec<Vector>> {
    let points = hull.points();
    let adjacency = hull.vertices_adj_to_face();
    let mut drop = vec![false; points.len()];
    let mut any = false;
    for face in hull.faces() {
        let first = face.first_vertex_or_edge as usize;
        let count = face.num_vertices_or_edges as usize;
        if count <= max_face {
            continue;
        }
        any = true;
        let ids: Vec<usize> = adjacency[first..first + count]
            .iter()
            .map(|&i| i as usize)
            .collect();
        let mut kept = vec![false; count];
        kept[0] = true;
        let mut nearest: Vec<f32> = ids
            .iter()
            .map(|&i| points[i].distance_squared(points[ids[0]]))
            .collect();
        for _ in 1..max_face {
            let (next, _) = nearest
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
                .expect("a big face has vertices");
            kept[next] = true;
            let p = points[ids[next]];
            for (d, &i) in nearest.iter_mut().zip(&ids) {
                *d = d.min(points[i].distance_squared(p));
            }
        }
        for (k, &i) in ids.iter().enumerate() {
            if !kept[k] {
                drop[i] = true;
            }
        }
    }
    any.then(|| {
        points
            .iter()
            .zip(&drop)
            .filter(|(_, d)| !**d)
            .map(|(p, _)| *p)
            .collect()
    })
}
