//! `lgdm sim grasp-data`: grasp images labelled by physics ([`lgdm_sim::datagen::grasp_data`]) —
//! options to a job, a progress bar, the counts and the throughput at the end.

use std::time::Instant;

use anyhow::Result;
use lgdm_sim::datagen::grasp_data::{GraspDataJob, GraspDataSetup, Randomise};
use lgdm_sim::run::config::ConfigOverrides;
use lgdm_sim::run::objects::ObjectSource;

use super::setup::{mesh_objects, report_meshes, resolve_config};
use super::{GraspDataArgs, cli_error};
use crate::output::outln;
use crate::progress::{ProgressMode, Reporter};

/// Runs `lgdm sim grasp-data`.
pub fn run(args: GraspDataArgs) -> Result<()> {
    let reporter = Reporter::new(args.progress);
    let jobs = crate::cmd::train::jobs(args.jobs)?;
    let procedural = ObjectSource::Procedural {
        instances: args.instances,
        seed: args.seed,
    };
    let overrides = ConfigOverrides {
        gripper: args.gripper,
        ..ConfigOverrides::default()
    };
    let setup = GraspDataSetup {
        scenes: args.scenes,
        seed: args.seed,
        objects: Some(mesh_objects(args.meshes.as_ref(), &args.units, procedural)?),
        isolated_share: args.isolated_share,
        views_per_scene: args.views_per_scene,
        analytic: args.analytic,
        random: args.random,
        rim: args.rim,
        randomise: if args.no_randomise {
            Randomise::none()
        } else {
            Randomise::default()
        },
        config: resolve_config(args.config.as_deref(), Some(&args.out), &overrides)?,
    };
    let job = GraspDataJob::prepare(setup).map_err(cli_error)?;
    report_meshes(job.library(), &reporter);
    let started = Instant::now();
    let mut task = reporter.bar("sim grasp-data", args.scenes as u64);
    let summary = job.run(&args.out, args.force, jobs, |p| {
        task.update_coarse(p.stage, p.done, p.total)
    });
    task.finish();
    let summary = summary.map_err(cli_error)?;
    let seconds = started.elapsed().as_secs_f64();
    let per_s = summary.all.tried as f64 / seconds.max(1e-9);
    reporter.event(&serde_json::json!({
        "event": "done",
        "out": args.out.display().to_string(),
        "images": summary.images,
        "grasps": summary.all.tried,
        "held": summary.all.held,
        "seconds": seconds,
        "grasps_per_second": per_s,
    }));
    if args.progress == ProgressMode::Jsonl {
        return Ok(());
    }
    outln!(
        "{} scenes → {} images, {} grasps tried in physics: {} held",
        summary.scenes,
        summary.images,
        summary.all.tried,
        summary.all.rate().describe()
    )?;
    for (source, t) in &summary.by_source {
        outln!("  {source:<9} {}", t.rate().describe())?;
    }
    for (table, t) in &summary.by_scenario {
        outln!("  {table:<9} {}", t.rate().describe())?;
    }
    let reasons: Vec<String> = summary
        .failures
        .iter()
        .map(|(k, n)| format!("{k} {n}"))
        .collect();
    outln!("  failures: {}", reasons.join(", "))?;
    outln!(
        "  the robot's planner would refuse {} of them (a pad closing on air); {} of those held",
        summary.refused_by_planner.tried,
        summary.refused_by_planner.held
    )?;
    outln!(
        "{:.1} labelled grasps per second ({seconds:.0} s, {jobs} job(s), {:.0} s simulated)",
        per_s,
        summary.sim_s
    )?;
    outln!("wrote {}", args.out.display())
}
