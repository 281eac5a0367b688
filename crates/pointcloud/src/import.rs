//! Import of user meshes from `<dir>/<category>/<instance>.{obj,stl,ply}`.
//!
//! Each mesh is checked (non-empty, finite, indices in range), converted to metres (a mesh
//! whose largest extent exceeds 100 units is taken to be in millimetres, one between 2 and 100
//! units in centimetres, otherwise metres), centred on the z axis and rested on z = 0 (z is
//! up). Anything broken or empty gives a [`MeshImportError`] naming the file.
//!
//! ```no_run
//! use lgdm_pointcloud::import::load_mesh_library;
//! let objects = load_mesh_library("my_meshes".as_ref()).unwrap();
//! println!("{} objects", objects.len());
//! ```

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use crate::mesh::Mesh;
use crate::objects::{ObjectModel, rest_on_table};

/// A mesh file (or directory) that could not be imported.
#[derive(Debug, Clone, thiserror::Error)]
#[error("mesh {}: {reason}", path.display())]
pub struct MeshImportError {
    /// The offending file or directory.
    pub path: PathBuf,
    /// What is wrong with it.
    pub reason: String,
}

fn fail(path: &Path, reason: impl Into<String>) -> MeshImportError {
    MeshImportError {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Units a mesh file was found to be in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LengthUnit {
    /// Metres (largest extent ≤ 2).
    Metre,
    /// Centimetres (largest extent in (2, 100]).
    Centimetre,
    /// Millimetres (largest extent > 100).
    Millimetre,
}

impl LengthUnit {
    /// Guesses the unit of a household object from its largest extent in file units.
    pub fn detect(largest_extent: f32) -> Self {
        if largest_extent > 100.0 {
            LengthUnit::Millimetre
        } else if largest_extent > 2.0 {
            LengthUnit::Centimetre
        } else {
            LengthUnit::Metre
        }
    }

    /// Metres per file unit.
    pub fn metres(self) -> f32 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 0.01,
            LengthUnit::Millimetre => 0.001,
        }
    }
}

const EXTENSIONS: [&str; 3] = ["obj", "stl", "ply"];

/// Loads every `<dir>/<category>/<instance>.{obj,stl,ply}` in sorted order (categories by
/// directory name, instances by file name). Instance names are the file stems and must be
/// unique across categories.
pub fn load_mesh_library(dir: &Path) -> Result<Vec<ObjectModel>, MeshImportError> {
    let sorted_entries = |d: &Path| -> Result<Vec<PathBuf>, MeshImportError> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d)
            .map_err(|e| fail(d, format!("cannot list: {e}")))?
            .map(|e| {
                e.map(|e| e.path())
                    .map_err(|err| fail(d, format!("cannot list: {err}")))
            })
            .collect::<Result<_, _>>()?;
        v.sort();
        Ok(v)
    };
    let mut objects: Vec<ObjectModel> = Vec::new();
    let mut sources: Vec<PathBuf> = Vec::new();
    for cat_dir in sorted_entries(dir)?.into_iter().filter(|p| p.is_dir()) {
        let category = cat_dir
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| fail(&cat_dir, "category directory name is not UTF-8"))?
            .to_string();
        if category.starts_with('.') {
            continue;
        }
        let mut found = 0;
        for file in sorted_entries(&cat_dir)? {
            let ext = file
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !file.is_file() || !ext.as_deref().is_some_and(|e| EXTENSIONS.contains(&e)) {
                continue;
            }
            let name = file
                .file_stem()
                .and_then(|n| n.to_str())
                .ok_or_else(|| fail(&file, "file name is not UTF-8"))?
                .to_string();
            if let Some(k) = objects.iter().position(|o| o.name == name) {
                return Err(fail(
                    &file,
                    format!(
                        "instance name `{name}` is also used by {}",
                        sources[k].display()
                    ),
                ));
            }
            let (mesh, _) = load_mesh(&file)?;
            objects.push(ObjectModel {
                name,
                category: category.clone(),
                mesh,
            });
            sources.push(file);
            found += 1;
        }
        if found == 0 {
            return Err(fail(
                &cat_dir,
                "category directory holds no .obj, .stl or .ply file",
            ));
        }
    }
    if objects.is_empty() {
        return Err(fail(
            dir,
            "no category directories with meshes (expected <dir>/<category>/<instance>.obj|stl|ply)",
        ));
    }
    Ok(objects)
}

/// Loads one mesh file, converts it to metres, centres it and rests it on z = 0.
pub fn load_mesh(path: &Path) -> Result<(Mesh, LengthUnit), MeshImportError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let mut mesh = match ext.as_deref() {
        Some("obj") => load_obj(path)?,
        Some("stl") => load_stl(path)?,
        Some("ply") => load_ply(path)?,
        _ => {
            return Err(fail(
                path,
                "unsupported extension (expected .obj, .stl or .ply)",
            ));
        }
    };
    check_mesh(path, &mesh)?;
    let (lo, hi) = mesh.bounds().ok_or_else(|| fail(path, "no vertices"))?;
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
    if extent <= 0.0 {
        return Err(fail(path, "all vertices coincide (zero size)"));
    }
    let unit = LengthUnit::detect(extent);
    let s = unit.metres();
    if s != 1.0 {
        mesh.scale_xyz([s, s, s]);
    }
    rest_on_table(&mut mesh);
    Ok((mesh, unit))
}

/// Checks that a mesh has triangles, finite vertices and in-range indices.
pub fn check_mesh(path: &Path, mesh: &Mesh) -> Result<(), MeshImportError> {
    if mesh.triangles.is_empty() {
        return Err(fail(path, "no triangles"));
    }
    if let Some(i) = mesh
        .vertices
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(fail(
            path,
            format!("vertex {i} has a non-finite coordinate"),
        ));
    }
    let n = mesh.vertices.len() as u32;
    if let Some(i) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v >= n))
    {
        return Err(fail(
            path,
            format!("triangle {i} refers to a vertex beyond the {n} vertices"),
        ));
    }
    if mesh.colors.len() != mesh.triangles.len() {
        return Err(fail(
            path,
            "internal: colour count differs from triangle count",
        ));
    }
    Ok(())
}

/// A deterministic colour for an imported mesh without one, from its file name.
fn default_color(path: &Path) -> [u8; 3] {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let h = crate::math::splitmix64(
        name.bytes()
            .fold(0u64, |a, b| a.wrapping_mul(131).wrapping_add(u64::from(b))),
    );
    [
        80 + (h & 0x7f) as u8,
        80 + ((h >> 8) & 0x7f) as u8,
        80 + ((h >> 16) & 0x7f) as u8,
    ]
}

fn load_obj(path: &Path) -> Result<Mesh, MeshImportError> {
    let file = File::open(path).map_err(|e| fail(path, format!("cannot open: {e}")))?;
    let mut reader = BufReader::new(file);
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let (models, materials) =
        tobj::load_obj_buf(&mut reader, &options, |mtl| tobj::load_mtl(base.join(mtl)))
            .map_err(|e| fail(path, format!("invalid OBJ: {e}")))?;
    let materials = materials.unwrap_or_default();
    let fallback = default_color(path);
    let mut mesh = Mesh::new();
    for model in models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(fail(
                path,
                format!("object `{}` has malformed arrays", model.name),
            ));
        }
        let color = m
            .material_id
            .and_then(|id| materials.get(id))
            .and_then(|mat| mat.diffuse)
            .map(|d| d.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
            .unwrap_or(fallback);
        let base = mesh.vertices.len() as u32;
        mesh.vertices
            .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        for t in m.indices.chunks_exact(3) {
            mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            mesh.colors.push(color);
        }
    }
    Ok(mesh)
}

fn load_stl(path: &Path) -> Result<Mesh, MeshImportError> {
    let mut file = File::open(path).map_err(|e| fail(path, format!("cannot open: {e}")))?;
    let stl = stl_io::read_stl(&mut file).map_err(|e| fail(path, format!("invalid STL: {e}")))?;
    let color = default_color(path);
    Ok(Mesh {
        vertices: stl.vertices.iter().map(|v| [v[0], v[1], v[2]]).collect(),
        triangles: stl
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| u32::try_from(i).unwrap_or(u32::MAX)))
            .collect(),
        colors: vec![color; stl.faces.len()],
    })
}

fn load_ply(path: &Path) -> Result<Mesh, MeshImportError> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let file = File::open(path).map_err(|e| fail(path, format!("cannot open: {e}")))?;
    let mut reader = BufReader::new(file);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| fail(path, format!("invalid PLY: {e}")))?;
    let scalar = |p: Option<&Property>| -> Option<f64> {
        Some(match p? {
            Property::Char(v) => f64::from(*v),
            Property::UChar(v) => f64::from(*v),
            Property::Short(v) => f64::from(*v),
            Property::UShort(v) => f64::from(*v),
            Property::Int(v) => f64::from(*v),
            Property::UInt(v) => f64::from(*v),
            Property::Float(v) => f64::from(*v),
            Property::Double(v) => *v,
            _ => return None,
        })
    };
    let index_list = |p: &Property| -> Option<Vec<i64>> {
        Some(match p {
            Property::ListChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Property::ListUChar(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Property::ListShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Property::ListUShort(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Property::ListInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
            Property::ListUInt(v) => v.iter().map(|&x| i64::from(x)).collect(),
            _ => return None,
        })
    };
    let vertices_el = ply
        .payload
        .get("vertex")
        .ok_or_else(|| fail(path, "no `vertex` element"))?;
    let mut vertices = Vec::with_capacity(vertices_el.len());
    let mut vertex_colors = Vec::with_capacity(vertices_el.len());
    for (i, v) in vertices_el.iter().enumerate() {
        let coord = |k: &str| {
            scalar(v.get(k)).ok_or_else(|| fail(path, format!("vertex {i} lacks a numeric `{k}`")))
        };
        vertices.push([coord("x")? as f32, coord("y")? as f32, coord("z")? as f32]);
        let c = |k: &str| scalar(v.get(k)).map(|x| x.clamp(0.0, 255.0) as u8);
        vertex_colors.push(match (c("red"), c("green"), c("blue")) {
            (Some(r), Some(g), Some(b)) => Some([r, g, b]),
            _ => None,
        });
    }
    let faces_el = ply
        .payload
        .get("face")
        .ok_or_else(|| fail(path, "no `face` element"))?;
    let fallback = default_color(path);
    let mut mesh = Mesh {
        vertices,
        ..Mesh::default()
    };
    let n = mesh.vertices.len() as i64;
    for (fi, f) in faces_el.iter().enumerate() {
        let list = f
            .get("vertex_indices")
            .or_else(|| f.get("vertex_index"))
            .and_then(index_list)
            .ok_or_else(|| {
                fail(
                    path,
                    format!("face {fi} lacks an integer list `vertex_indices`"),
                )
            })?;
        if list.len() < 3 {
            return Err(fail(path, format!("face {fi} has fewer than 3 vertices")));
        }
        if let Some(&bad) = list.iter().find(|&&i| i < 0 || i >= n) {
            return Err(fail(
                path,
                format!("face {fi} refers to vertex {bad}, but there are {n}"),
            ));
        }
        for k in 1..list.len() - 1 {
            let tri = [list[0] as u32, list[k] as u32, list[k + 1] as u32];
            let colors: Vec<[u8; 3]> = tri
                .iter()
                .filter_map(|&i| vertex_colors[i as usize])
                .collect();
            let color = if colors.len() == 3 {
                let avg = |c: usize| {
                    ((u32::from(colors[0][c]) + u32::from(colors[1][c]) + u32::from(colors[2][c]))
                        / 3) as u8
                };
                [avg(0), avg(1), avg(2)]
            } else {
                fallback
            };
            mesh.triangles.push(tri);
            mesh.colors.push(color);
        }
    }
    Ok(mesh)
}
