//! The world's dynamic objects from outside: the handle that names one ([`ObjectHandle`]) and
//! its collider drawn as triangles in the mesh's colours (what the cameras show with
//! `ObjectDrawing::Colliders`).

use lgdm_pointcloud::mesh::Mesh;
use serde::{Deserialize, Serialize};

use crate::physics::rapier::RVec;

/// A dynamic object in the [`World`](crate::physics::world::World) (an index; stays valid until the
/// object is removed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ObjectHandle(pub u32);

/// Meshes with more triangles than this are coloured from a simplified copy (vertex clustering
/// on cells of a 128th of the mesh's extent, [`Mesh::clustered`]) searched through a
/// bounding-volume tree, instead of trying every triangle for every drawn face (default 10,000;
/// the procedural library's meshes have at most 2,432, so their drawings are what they were).
/// Trying every triangle of a 2-million-triangle scan takes hours; a tree over all of them
/// takes 400 MB.
const MAX_DRAWING_COLOR_TRIANGLES: usize = 10_000;

/// Triangles of the convex hulls of `parts` (object frame), each coloured like the mesh triangle
/// nearest its centroid (of a simplified mesh above [`MAX_DRAWING_COLOR_TRIANGLES`]).
pub(crate) fn collider_drawing(parts: &[Vec<RVec>], mesh: &Mesh) -> Mesh {
    use rapier3d::parry::query::{PointQuery, PointQueryWithLocation};
    use rapier3d::parry::shape::{TriMesh, Triangle};
    let coarse = match mesh.bounds() {
        Some((lo, hi)) if mesh.triangles.len() > MAX_DRAWING_COLOR_TRIANGLES => {
            let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
            Some(mesh.clustered(extent / 128.0))
        }
        _ => None,
    };
    let tree = coarse.as_ref().and_then(|coarse| {
        let vertices = coarse
            .vertices
            .iter()
            .map(|v| RVec::from_array(*v))
            .collect();
        let tree = TriMesh::new(vertices, coarse.triangles.clone()).ok()?;
        Some((tree, &coarse.colors))
    });
    let mesh_triangles: Vec<(Triangle, [u8; 3])> = match tree {
        Some(_) => Vec::new(),
        None => mesh
            .triangles
            .iter()
            .zip(&mesh.colors)
            .map(|(t, c)| {
                let v = |i: u32| RVec::from_array(mesh.vertices[i as usize]);
                (Triangle::new(v(t[0]), v(t[1]), v(t[2])), *c)
            })
            .collect(),
    };
    let mut out = Mesh::new();
    for part in parts {
        if part.len() < 4 {
            continue;
        }
        let (vertices, faces) = rapier3d::parry::transformation::convex_hull(part);
        for [a, b, c] in faces {
            let (a, b, c) = (
                vertices[a as usize],
                vertices[b as usize],
                vertices[c as usize],
            );
            let centroid = (a + b + c) / 3.0;
            let color = match &tree {
                Some((tree, colors)) => {
                    let (_, (i, _)) = tree.project_local_point_and_get_location(centroid, true);
                    colors.get(i as usize).copied().unwrap_or([128; 3])
                }
                None => mesh_triangles
                    .iter()
                    .map(|(t, c)| (t.distance_to_local_point(centroid, true), *c))
                    .min_by(|x, y| x.0.total_cmp(&y.0))
                    .map_or([128; 3], |(_, c)| c),
            };
            out.push_triangle(a.to_array(), b.to_array(), c.to_array(), color);
        }
    }
    out
}
