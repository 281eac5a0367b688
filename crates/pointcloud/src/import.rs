//! Import of user meshes from `<dir>/<category>/<instance>.{obj,stl,ply}`.
//!
//! Each mesh is checked (non-empty, finite, indices in range, at most [`MAX_MESH_TRIANGLES`]
//! triangles and [`MAX_MESH_VERTICES`] vertices), converted to metres, centred on the z axis and
//! rested on z = 0 (z is up). Anything broken, empty or too big gives a [`MeshImportError`]
//! naming the file.
//!
//! Units: a mesh file has no unit, so it is either given ([`MeshUnits`]: one unit for every
//! file and/or one per file) or guessed from the size: the guess is the unit in which the
//! mesh's largest extent is that of a household object, 2 cm to 60 cm
//! ([`LengthUnit::plausible_units`]). Exactly one such unit → it is used and reported
//! ([`ImportReport`]); two (an extent of 20 to 60 file units: 43 is a 43 mm golf ball or a
//! 43 cm vase) or none → an error asking for the unit. Centimetres and metres never compete
//! (a factor of 100 is more than the 30 between 2 cm and 60 cm); millimetres and centimetres
//! do for extents of 20 to 60.
//!
//! ```no_run
//! use lgdm_pointcloud::import::{LengthUnit, MeshUnits, load_mesh_library};
//! let objects = load_mesh_library("my_meshes".as_ref(), &MeshUnits::guess()).unwrap();
//! for o in &objects {
//!     println!("{}: {}", o.report.file, o.report.describe());
//! }
//! let all_mm = MeshUnits::parse(&["mm"]).unwrap();
//! assert_eq!(all_mm.all, Some(LengthUnit::Millimetre));
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::mesh::Mesh;
use crate::objects::{ObjectModel, rest_on_table};
use crate::sidecar::{ObjectProps, SIDECAR_FILE, Sidecar, SidecarError};

/// Lower limit of a plausible household object's largest extent, millimetres (20 mm).
pub const MIN_OBJECT_EXTENT_MM: f64 = 20.0;
/// Upper limit of a plausible household object's largest extent, millimetres (600 mm; the
/// default turntable camera sees about 0.6 m top to bottom).
pub const MAX_OBJECT_EXTENT_MM: f64 = 600.0;

/// Most triangles a mesh file may have (10,000,000). Real scans of household objects have up to a
/// few million, and dense meshes are simplified before the physics uses them
/// (`lgdm_sim::physics::hull`, `lgdm_sim::physics::shapes`); loading a 2-million-triangle STL peaks
/// at 145 MB, so one of 10 million would take about 0.7 GB. A binary STL or a PLY says its size in
/// its header and is refused before it is read; an OBJ after.
pub const MAX_MESH_TRIANGLES: usize = 10_000_000;

/// Most vertices a mesh file may have (10,000,000; see [`MAX_MESH_TRIANGLES`]).
pub const MAX_MESH_VERTICES: usize = 10_000_000;

/// A mesh file (or directory) that could not be imported.
#[derive(Debug, Clone, thiserror::Error)]
pub enum MeshImportError {
    /// The file or directory is unreadable, broken or empty.
    #[error("mesh {}: {reason}", path.display())]
    Invalid {
        /// The offending file or directory.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The library's `objects.toml` cannot be used.
    #[error(transparent)]
    Sidecar(#[from] SidecarError),
    /// The mesh's size fits more than one unit; the unit must be given.
    #[error(
        "mesh {}: cannot tell its unit: its largest extent, {} file units, is household-sized \
         (2 cm to 60 cm) in more than one unit: {}; give the unit: --units mm|cm|m (every mesh) \
         or --units {file}=mm|cm|m (this file); in Python units=",
        path.display(), fmt_sig(f64::from(*largest_extent)),
        describe_units(*largest_extent, candidates, " or ")
    )]
    AmbiguousUnit {
        /// The mesh file.
        path: PathBuf,
        /// The file as `--units FILE=UNIT` names it (relative to the meshes directory; just the
        /// file name from [`load_mesh`]).
        file: String,
        /// Largest extent of the bounding box, file units.
        largest_extent: f32,
        /// The units in which that extent is household-sized, smallest first.
        candidates: Vec<LengthUnit>,
    },
    /// The mesh's size is household-sized in no unit; the unit must be given.
    #[error(
        "mesh {}: cannot tell its unit: its largest extent, {} file units, is household-sized \
         (2 cm to 60 cm) in no unit: {}; give the unit: --units mm|cm|m (every mesh) or \
         --units {file}=mm|cm|m (this file); in Python units=",
        path.display(), fmt_sig(f64::from(*largest_extent)),
        describe_units(*largest_extent, &LengthUnit::ALL, ", ")
    )]
    NoPlausibleUnit {
        /// The mesh file.
        path: PathBuf,
        /// The file as `--units FILE=UNIT` names it (relative to the meshes directory; just the
        /// file name from [`load_mesh`]).
        file: String,
        /// Largest extent of the bounding box, file units.
        largest_extent: f32,
    },
    /// A unit was given for a file that is not in the meshes directory.
    #[error(
        "meshes {}: a unit is given for `{file}`, but there is no such mesh file (give files \
         as <category>/<file>, e.g. `{example}`)",
        dir.display()
    )]
    UnknownUnitFile {
        /// The meshes directory.
        dir: PathBuf,
        /// The file named in the units.
        file: String,
        /// A file that exists, as an example of the naming.
        example: String,
    },
}

impl MeshImportError {
    /// The file or directory the error is about.
    pub fn path(&self) -> &Path {
        match self {
            MeshImportError::Invalid { path, .. }
            | MeshImportError::AmbiguousUnit { path, .. }
            | MeshImportError::NoPlausibleUnit { path, .. } => path,
            MeshImportError::UnknownUnitFile { dir, .. } => dir,
            MeshImportError::Sidecar(e) => &e.path,
        }
    }
}

fn fail(path: &Path, reason: impl Into<String>) -> MeshImportError {
    MeshImportError::Invalid {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// `x` with four significant digits, trailing zeros dropped (`43`, `0.043`, `1500`).
fn fmt_sig(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    let decimals = (3 - x.abs().log10().floor() as i64).clamp(0, 12) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// `43 mm = 0.043 m or 43 cm = 0.43 m`.
fn describe_units(largest_extent: f32, units: &[LengthUnit], sep: &str) -> String {
    let x = fmt_sig(f64::from(largest_extent));
    units
        .iter()
        .map(|u| match u {
            LengthUnit::Metre => format!("{x} m"),
            _ => format!("{x} {u} = {} m", fmt_sig(u.extent_m(largest_extent))),
        })
        .collect::<Vec<_>>()
        .join(sep)
}

/// Whether a largest extent of `mm` millimetres is a household object's, with a relative
/// slack of 10⁻⁶ for f32 coordinates (`0.6` in a file is a hair over 0.6).
fn plausible_mm(mm: f64) -> bool {
    (MIN_OBJECT_EXTENT_MM * (1.0 - 1e-6)..=MAX_OBJECT_EXTENT_MM * (1.0 + 1e-6)).contains(&mm)
}

/// The unit of a mesh file's coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LengthUnit {
    /// Metres (`m`).
    #[serde(rename = "m")]
    Metre,
    /// Centimetres (`cm`).
    #[serde(rename = "cm")]
    Centimetre,
    /// Millimetres (`mm`).
    #[serde(rename = "mm")]
    Millimetre,
}

impl LengthUnit {
    /// Every unit, smallest first.
    pub const ALL: [LengthUnit; 3] = [
        LengthUnit::Millimetre,
        LengthUnit::Centimetre,
        LengthUnit::Metre,
    ];

    /// `mm`, `cm` or `m`.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Millimetre => "mm",
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

    /// Millimetres per file unit (exact in f64).
    fn millimetres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1000.0,
            LengthUnit::Centimetre => 10.0,
            LengthUnit::Millimetre => 1.0,
        }
    }

    /// `largest_extent` file units in metres.
    fn extent_m(self, largest_extent: f32) -> f64 {
        f64::from(largest_extent) * self.millimetres() / 1000.0
    }

    /// Whether `largest_extent` file units in this unit is a household object's size:
    /// [`MIN_OBJECT_EXTENT_MM`] to [`MAX_OBJECT_EXTENT_MM`] (inclusive, give or take f32
    /// rounding).
    pub fn is_plausible(self, largest_extent: f32) -> bool {
        plausible_mm(f64::from(largest_extent) * self.millimetres())
    }

    /// The units, smallest first, in which a mesh whose largest extent is `largest_extent`
    /// file units is household-sized. The guess is the unit when there is exactly one.
    pub fn plausible_units(largest_extent: f32) -> Vec<LengthUnit> {
        LengthUnit::ALL
            .into_iter()
            .filter(|u| u.is_plausible(largest_extent))
            .collect()
    }
}

impl fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

impl FromStr for LengthUnit {
    type Err = String;

    /// `mm`, `cm` or `m`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "mm" => Ok(LengthUnit::Millimetre),
            "cm" => Ok(LengthUnit::Centimetre),
            "m" => Ok(LengthUnit::Metre),
            other => Err(format!("unknown unit `{other}` (expected mm, cm or m)")),
        }
    }
}

/// The units of a mesh library's files: one for every file, per-file exceptions, or (the
/// default) guessed per file from its size.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshUnits {
    /// The unit of every file not listed in `files` (default: guessed per file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub all: Option<LengthUnit>,
    /// Units of single files, by path relative to the meshes directory (`ball/golf.obj`); they
    /// take precedence over `all` (default: none).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub files: BTreeMap<String, LengthUnit>,
}

impl MeshUnits {
    /// Every unit guessed (the default).
    pub fn guess() -> MeshUnits {
        MeshUnits::default()
    }

    /// Whether every unit is guessed (nothing given).
    pub fn is_guess(&self) -> bool {
        self.all.is_none() && self.files.is_empty()
    }

    /// Parses `--units` arguments: `UNIT` (every file) or `<category>/<file>=UNIT` (one
    /// file), with `UNIT` one of `mm`, `cm`, `m`. Each file and the every-file unit may be
    /// given once.
    pub fn parse<S: AsRef<str>>(entries: &[S]) -> Result<MeshUnits, String> {
        let mut units = MeshUnits::default();
        for entry in entries {
            let entry = entry.as_ref().trim();
            match entry.rsplit_once('=') {
                None => {
                    let unit = entry.parse()?;
                    if units.all.replace(unit).is_some() {
                        return Err(format!(
                            "the unit of every mesh is given twice (`{entry}`); give one, and \
                             per-file units as <category>/<file>=UNIT"
                        ));
                    }
                }
                Some((file, unit)) => {
                    let file = file.trim().to_string();
                    let unit = unit.trim().parse().map_err(|e| format!("`{entry}`: {e}"))?;
                    if units.files.insert(file.clone(), unit).is_some() {
                        return Err(format!("the unit of `{file}` is given twice"));
                    }
                }
            }
        }
        units.check()?;
        Ok(units)
    }

    /// Checks the per-file names: `<category>/<file>` with `/`, inside the directory.
    pub fn check(&self) -> Result<(), String> {
        for file in self.files.keys() {
            if !is_file_key(file) {
                return Err(format!(
                    "per-file unit for `{file}`: name the file as <category>/<file> relative to \
                     the meshes directory (e.g. `mug/mug_01.obj`)"
                ));
            }
        }
        Ok(())
    }

    /// The given unit of `file` (`<category>/<file>`) and where it came from, `None` when it
    /// is to be guessed.
    pub fn given(&self, file: &str) -> Option<(LengthUnit, UnitSource)> {
        self.files
            .get(file)
            .map(|&u| (u, UnitSource::GivenForFile))
            .or(self.all.map(|u| (u, UnitSource::Given)))
    }
}

/// Whether `file` names a library file as `<category>/<file>`: two plain parts, inside the
/// meshes directory (how `--units` and `objects.toml` name a file).
pub(crate) fn is_file_key(file: &str) -> bool {
    let parts: Vec<&str> = file.split('/').collect();
    parts.len() == 2
        && parts
            .iter()
            .all(|p| !(p.is_empty() || *p == "." || *p == ".." || p.contains('\\')))
}

/// How a mesh's unit was chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnitSource {
    /// Guessed from the size ([`LengthUnit::plausible_units`]).
    Guessed,
    /// Given for every mesh ([`MeshUnits::all`]).
    Given,
    /// Given for this file ([`MeshUnits::files`]).
    GivenForFile,
    /// Given by the library's sidecar ([`crate::sidecar`], `objects.toml`).
    Sidecar,
}

/// What importing one mesh file found: its unit, how the unit was chosen and the resulting
/// size. Recorded per instance in a dataset's manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImportReport {
    /// The mesh file, relative to the meshes directory (`cup/espresso.obj`).
    pub file: String,
    /// The unit of the file's coordinates.
    pub unit: LengthUnit,
    /// Guessed or given.
    pub unit_source: UnitSource,
    /// Largest extent of the imported mesh's bounding box, metres.
    pub largest_extent_m: f32,
    /// What the library's sidecar (`objects.toml`) set for this file.
    #[serde(default, skip_serializing_if = "ObjectProps::is_empty")]
    pub sidecar: ObjectProps,
}

impl ImportReport {
    /// Whether the imported size is a household object's (2 cm to 60 cm); always true for a
    /// guessed unit, and worth a warning when false for a given one.
    pub fn is_plausible(&self) -> bool {
        LengthUnit::Metre.is_plausible(self.largest_extent_m)
    }

    /// `units mm (guessed), largest extent 0.062 m`.
    pub fn describe(&self) -> String {
        let source = match self.unit_source {
            UnitSource::Guessed => "guessed",
            UnitSource::Given => "given",
            UnitSource::GivenForFile => "given for this file",
            UnitSource::Sidecar => "from objects.toml",
        };
        format!(
            "units {} ({source}), largest extent {} m",
            self.unit,
            fmt_sig(f64::from(self.largest_extent_m))
        )
    }
}

/// An imported mesh: the object and how its unit was chosen.
#[derive(Debug, Clone)]
pub struct ImportedObject {
    /// The object, metres.
    pub object: ObjectModel,
    /// Its file, unit and size.
    pub report: ImportReport,
}

const EXTENSIONS: [&str; 3] = ["obj", "stl", "ply"];

/// Loads every `<dir>/<category>/<instance>.{obj,stl,ply}` in sorted order (categories by
/// directory name, instances by file name), in the units `units` gives, the sidecar
/// (`<dir>/objects.toml`, [`crate::sidecar`]) gives, or guessed — in that order — and with the
/// sidecar's rest pose and colour. Instance names are the file stems and must be unique across
/// categories; every file named in `units.files` or the sidecar must exist.
pub fn load_mesh_library(
    dir: &Path,
    units: &MeshUnits,
) -> Result<Vec<ImportedObject>, MeshImportError> {
    units.check().map_err(|reason| fail(dir, reason))?;
    let sidecar = Sidecar::read(dir)?;
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
    // First the files (category, instance name, `<category>/<file>`, path), so that a unit
    // given for a file that is not there is reported before any mesh is read.
    let mut found: Vec<(String, String, String, PathBuf)> = Vec::new();
    for cat_dir in sorted_entries(dir)?.into_iter().filter(|p| p.is_dir()) {
        let category = cat_dir
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| fail(&cat_dir, "category directory name is not UTF-8"))?
            .to_string();
        if category.starts_with('.') {
            continue;
        }
        let before = found.len();
        for file in sorted_entries(&cat_dir)? {
            let ext = file
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !file.is_file() || !ext.as_deref().is_some_and(|e| EXTENSIONS.contains(&e)) {
                continue;
            }
            let (Some(name), Some(file_name)) = (
                file.file_stem().and_then(|n| n.to_str()),
                file.file_name().and_then(|n| n.to_str()),
            ) else {
                return Err(fail(&file, "file name is not UTF-8"));
            };
            if let Some(other) = found.iter().find(|f| f.1 == name) {
                return Err(fail(
                    &file,
                    format!(
                        "instance name `{name}` is also used by {}",
                        other.3.display()
                    ),
                ));
            }
            let key = format!("{category}/{file_name}");
            found.push((category.clone(), name.to_string(), key, file));
        }
        if found.len() == before {
            return Err(fail(
                &cat_dir,
                "category directory holds no .obj, .stl or .ply file",
            ));
        }
    }
    if found.is_empty() {
        return Err(fail(
            dir,
            "no category directories with meshes (expected <dir>/<category>/<instance>.obj|stl|ply)",
        ));
    }
    if let Some(file) = units
        .files
        .keys()
        .find(|f| !found.iter().any(|(_, _, key, _)| key == *f))
    {
        return Err(MeshImportError::UnknownUnitFile {
            dir: dir.to_path_buf(),
            file: file.clone(),
            example: found[0].2.clone(),
        });
    }
    if let Some(file) = sidecar
        .files
        .keys()
        .find(|f| !found.iter().any(|(_, _, key, _)| key == *f))
    {
        return Err(MeshImportError::Sidecar(SidecarError {
            path: dir.join(SIDECAR_FILE),
            reason: format!(
                "files.\"{file}\": no such mesh in {} (files are named as <category>/<file>, \
                 e.g. \"{}\")",
                dir.display(),
                found[0].2
            ),
        }));
    }
    found
        .into_iter()
        .map(|(category, name, key, path)| {
            let props = sidecar.props(&key);
            let given = units
                .given(&key)
                .or(props.unit.map(|u| (u, UnitSource::Sidecar)));
            let (mesh, report) = import_mesh(&path, key, given, &props)?;
            Ok(ImportedObject {
                object: ObjectModel {
                    name,
                    category,
                    mesh,
                    physics: props.physics(),
                    parts: Vec::new(),
                },
                report,
            })
        })
        .collect()
}

/// Loads one mesh file, guessing its unit ([`LengthUnit::plausible_units`]; an ambiguous or
/// implausible size is an error), converts it to metres, centres it and rests it on z = 0.
pub fn load_mesh(path: &Path) -> Result<(Mesh, LengthUnit), MeshImportError> {
    let (mesh, report) = import_mesh(path, file_label(path), None, &ObjectProps::default())?;
    Ok((mesh, report.unit))
}

/// Loads one mesh file whose coordinates are in `unit`, converts it to metres, centres it and
/// rests it on z = 0.
pub fn load_mesh_in(path: &Path, unit: LengthUnit) -> Result<Mesh, MeshImportError> {
    let (mesh, _) = import_mesh(
        path,
        file_label(path),
        Some((unit, UnitSource::Given)),
        &ObjectProps::default(),
    )?;
    Ok(mesh)
}

fn file_label(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// Reads, checks, converts (given unit or guessed), centres and rests one mesh file; `file` is
/// how reports and errors name it.
fn import_mesh(
    path: &Path,
    file: String,
    given: Option<(LengthUnit, UnitSource)>,
    props: &ObjectProps,
) -> Result<(Mesh, ImportReport), MeshImportError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    check_declared_size(path, ext.as_deref())?;
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
    if !extent.is_finite() {
        return Err(fail(path, "coordinates too large (the extent overflows)"));
    }
    if extent <= 0.0 {
        return Err(fail(path, "all vertices coincide (zero size)"));
    }
    let (unit, unit_source) = match given {
        Some(g) => g,
        None => match LengthUnit::plausible_units(extent)[..] {
            [unit] => (unit, UnitSource::Guessed),
            [] => {
                return Err(MeshImportError::NoPlausibleUnit {
                    path: path.to_path_buf(),
                    file,
                    largest_extent: extent,
                });
            }
            ref candidates => {
                return Err(MeshImportError::AmbiguousUnit {
                    path: path.to_path_buf(),
                    file,
                    largest_extent: extent,
                    candidates: candidates.to_vec(),
                });
            }
        },
    };
    let s = unit.metres();
    if s != 1.0 {
        mesh.scale_xyz([s, s, s]);
    }
    if let Some(rotation) = props.rest_rotation() {
        mesh = mesh.transformed(&rotation);
    }
    if let Some(rgb) = props.rgb() {
        mesh.colors.fill(rgb);
    }
    rest_on_table(&mut mesh);
    let largest_extent_m = mesh
        .bounds()
        .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max))
        .unwrap_or(0.0);
    Ok((
        mesh,
        ImportReport {
            file,
            unit,
            unit_source,
            largest_extent_m,
            sidecar: props.clone(),
        },
    ))
}

/// The error for a mesh of `count` `what`s, more than `limit`.
fn too_big(path: &Path, count: usize, what: &str, limit: usize) -> MeshImportError {
    fail(
        path,
        format!(
            "{count} {what}, more than the {limit} a mesh may have (simplify it first, e.g. \
             decimate it in MeshLab or Blender)"
        ),
    )
}

/// Refuses a binary STL or a PLY whose header declares more than [`MAX_MESH_TRIANGLES`]
/// triangles or [`MAX_MESH_VERTICES`] vertices, before the file is read; anything it cannot
/// tell from the header is left to [`check_mesh`].
fn check_declared_size(path: &Path, ext: Option<&str>) -> Result<(), MeshImportError> {
    use std::io::{BufRead, Read};
    let Ok(file) = File::open(path) else {
        return Ok(()); // the loader reports it
    };
    match ext {
        Some("stl") => {
            let len = file.metadata().map(|m| m.len()).unwrap_or(0);
            let mut header = [0u8; 84];
            if (&file).read_exact(&mut header).is_err() {
                return Ok(());
            }
            let count = u64::from(u32::from_le_bytes([
                header[80], header[81], header[82], header[83],
            ]));
            // A binary STL is exactly 84 bytes and 50 a triangle; anything else is ASCII.
            if len == 84 + 50 * count && count > MAX_MESH_TRIANGLES as u64 {
                return Err(too_big(
                    path,
                    count as usize,
                    "triangles",
                    MAX_MESH_TRIANGLES,
                ));
            }
        }
        Some("ply") => {
            let reader = BufReader::new(file);
            for line in reader.split(b'\n').take(1000) {
                let Ok(line) = line else {
                    break;
                };
                let line = String::from_utf8_lossy(&line);
                let words: Vec<&str> = line.split_whitespace().collect();
                match words[..] {
                    ["end_header"] => break,
                    ["element", "face", n] => {
                        if let Ok(n) = n.parse::<usize>()
                            && n > MAX_MESH_TRIANGLES
                        {
                            return Err(too_big(path, n, "faces", MAX_MESH_TRIANGLES));
                        }
                    }
                    ["element", "vertex", n] => {
                        if let Ok(n) = n.parse::<usize>()
                            && n > MAX_MESH_VERTICES
                        {
                            return Err(too_big(path, n, "vertices", MAX_MESH_VERTICES));
                        }
                    }
                    _ => {}
                }
            }
        }
        _ => {}
    }
    Ok(())
}

/// Checks that a mesh has triangles (at most [`MAX_MESH_TRIANGLES`]), finite vertices (at most
/// [`MAX_MESH_VERTICES`]) and in-range indices.
pub fn check_mesh(path: &Path, mesh: &Mesh) -> Result<(), MeshImportError> {
    if mesh.triangles.is_empty() {
        return Err(fail(path, "no triangles"));
    }
    if mesh.triangles.len() > MAX_MESH_TRIANGLES {
        return Err(too_big(
            path,
            mesh.triangles.len(),
            "triangles",
            MAX_MESH_TRIANGLES,
        ));
    }
    if mesh.vertices.len() > MAX_MESH_VERTICES {
        return Err(too_big(
            path,
            mesh.vertices.len(),
            "vertices",
            MAX_MESH_VERTICES,
        ));
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
    // tobj 4.0 multiplies face indices unchecked (`vn * 3 + 2`): with overflow checks (debug
    // builds) a huge normal or texture index panics. A panic there is an invalid file.
    let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |mtl| {
            // Only a regular file of at most 16 MiB: `mtllib /dev/zero` (or a FIFO) would be
            // read without end. Anything else leaves the default colour, as a missing file does.
            let mtl = base.join(mtl);
            match std::fs::metadata(&mtl) {
                Ok(meta) if meta.is_file() && meta.len() <= 16 << 20 => tobj::load_mtl(mtl),
                _ => Err(tobj::LoadError::OpenFileFailed),
            }
        })
    }))
    .map_err(|_| fail(path, "invalid OBJ: a face index out of range"))?;
    let (models, materials) = loaded.map_err(|e| fail(path, format!("invalid OBJ: {e}")))?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A mesh above the size limit is refused, naming the file, from its header alone: a PLY
    /// declaring 20 million faces (and nothing else), a binary STL of 10,000,001 triangles (a
    /// sparse file: nothing is read past the header).
    #[test]
    fn meshes_above_the_limit_are_refused_by_their_header() {
        let dir = tempfile::tempdir().unwrap();
        let ply = dir.path().join("huge.ply");
        std::fs::write(
            &ply,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 20000000\nproperty list uchar int vertex_indices\n\
             end_header\n",
        )
        .unwrap();
        let err = load_mesh_in(&ply, LengthUnit::Metre)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("huge.ply") && err.contains("20000000 faces, more than the 10000000"),
            "{err}"
        );
        let stl = dir.path().join("huge.stl");
        let count = MAX_MESH_TRIANGLES as u32 + 1;
        let file = File::create(&stl).unwrap();
        let mut header = vec![0u8; 84];
        header[80..].copy_from_slice(&count.to_le_bytes());
        std::io::Write::write_all(&mut &file, &header).unwrap();
        file.set_len(84 + 50 * u64::from(count)).unwrap();
        let err = load_mesh_in(&stl, LengthUnit::Metre)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("huge.stl") && err.contains("10000001 triangles, more than the"),
            "{err}"
        );
    }
}
