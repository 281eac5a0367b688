//! From the options of `lgdm sim` to the library's setups: the objects, the config with the
//! options on top, recording, the output, a resumed run's record, a new pick-place or packing
//! setup; and the imported meshes as the run reports them.

use std::path::Path;

use anyhow::{Result, bail};
use lgdm_pointcloud::import::MeshUnits;
use lgdm_sim::recognition::config::RecognitionConfig;
use lgdm_sim::recognition::encoder::{GoodEncoder, ViewEncoder};
use lgdm_sim::run::config::{ConfigOverrides, SimConfig};
use lgdm_sim::run::job::{JobRecord, Output, PickPlaceSetup};
use lgdm_sim::run::objects::{ObjectLibrary, ObjectSource};
use lgdm_sim::run::record::RecordConfig;

use super::{GraspArg, PickPlaceArgs, RobotArgs, cli_error};
use crate::data::Encoder;
use crate::progress::Reporter;

/// The objects of `--meshes` (with `--units`), else the procedural ones.
pub(super) fn objects(args: &RobotArgs, procedural: ObjectSource) -> Result<ObjectSource> {
    mesh_objects(args.meshes.as_ref(), &args.units, procedural)
}

/// The objects of `meshes` (with `units`), else `procedural`.
pub(super) fn mesh_objects(
    meshes: Option<&std::path::PathBuf>,
    units: &[String],
    procedural: ObjectSource,
) -> Result<ObjectSource> {
    let Some(dir) = meshes else {
        return Ok(procedural);
    };
    let units = MeshUnits::parse(units).map_err(|reason| anyhow::anyhow!("--units: {reason}"))?;
    Ok(ObjectSource::Meshes {
        dir: dir.clone(),
        units,
    })
}

/// Each imported mesh's unit and size, with a warning for one that is not household-sized.
pub(super) fn report_meshes(library: &ObjectLibrary, reporter: &Reporter) {
    for report in &library.imported {
        let warning = if report.is_plausible() {
            ""
        } else {
            " (not the 2 cm to 60 cm of a household object: check --units)"
        };
        reporter.message(&format!(
            "mesh {}: {}{warning}",
            report.file,
            report.describe()
        ));
    }
}

/// The run's constants: `--config`'s file (else the defaults), with what the options set — the
/// gripper, the cameras' drawing, the colliders — on top. Checked whole, naming the field.
pub(super) fn sim_config(args: &RobotArgs) -> Result<SimConfig> {
    let overrides = ConfigOverrides {
        gripper: args.gripper,
        draw: args.draw,
        shapes: args.shapes,
        proposal_check: args.proposal_check,
    };
    resolve_config(args.config.as_deref(), args.out.as_deref(), &overrides)
}

/// `config` (else the defaults) with `overrides` on top, refused inside `out`.
pub(super) fn resolve_config(
    config: Option<&Path>,
    out: Option<&Path>,
    overrides: &ConfigOverrides,
) -> Result<SimConfig> {
    if let (Some(config), Some(out)) = (config, out)
        && let (Ok(config), Ok(out)) = (config.canonicalize(), out.canonicalize())
        && config.starts_with(&out)
    {
        bail!(
            "--config {} is inside --out {}: a run does not write over its inputs; copy it out \
             first",
            config.display(),
            out.display()
        );
    }
    SimConfig::resolve(config, overrides).map_err(|e| anyhow::anyhow!("--config {e}"))
}

/// `--record` / `--record-rounds`.
pub(super) fn record_config(args: &RobotArgs) -> Option<RecordConfig> {
    (args.record || args.record_rounds.is_some()).then(|| RecordConfig {
        first_rounds: args.record_rounds,
        ..RecordConfig::default()
    })
}

pub(super) fn output(args: &RobotArgs) -> Option<Output> {
    args.out.clone().map(|dir| Output {
        dir,
        force: args.force,
    })
}

/// The grasp source a resumed run's record names.
pub(super) fn recorded_grasp(name: &str) -> Result<GraspArg> {
    match name {
        "analytic" => Ok(GraspArg::Analytic),
        "random" => Ok(GraspArg::Random),
        "network" => Ok(GraspArg::Network),
        other => bail!("the run's record names an unknown grasp source `{other}`"),
    }
}

/// The job record of the run `--resume` names, with its setup pointed at that directory.
pub(super) fn resumed(dir: &Path) -> Result<(JobRecord, Output)> {
    let record = JobRecord::read(dir).map_err(cli_error)?;
    Ok((record, Output::new(dir)))
}

/// The setup of a new pick-place or packing run from its options.
pub(super) fn new_pick_place(
    args: &PickPlaceArgs,
    targets: Option<Vec<String>>,
) -> Result<PickPlaceSetup> {
    let robot = &args.robot;
    let procedural = ObjectSource::Procedural {
        instances: 5,
        seed: args.object_seed,
    };
    let encoder_dim = match args.encoder {
        Encoder::Good => GoodEncoder.dim(),
        Encoder::Ae => crate::data::ae::FEATURE_DIM,
    };
    Ok(PickPlaceSetup {
        scenario: args.scenario.into(),
        rounds: args.rounds,
        attempts: args.attempts,
        seed: args.seed,
        objects: objects(robot, procedural)?,
        set_size: args.objects,
        model: args.model.clone(),
        recognition: RecognitionConfig {
            replay: !args.no_replay,
            learn_known: args.learn_always,
            confidence_threshold: args.confidence,
            ..RecognitionConfig::default()
        },
        encoder: (args.encoder.name().to_string(), encoder_dim),
        targets,
        arrive_after: args.arrive_after,
        config: sim_config(robot)?,
        record: record_config(robot),
        out: output(robot),
        ae_checkpoint: robot.ae_checkpoint.clone(),
    })
}
