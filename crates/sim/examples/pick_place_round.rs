//! One round of the paper's pick-and-place from library calls only: the default object set
//! (the embedded dataset's 15 procedural objects), an empty model and the simulated teacher,
//! analytic grasps, GOOD features — and the run directory the binary writes, model included.
//!
//! ```sh
//! cargo run --release -p lgdm-sim --example pick_place_round [OUT_DIR]
//! ```
//!
//! The test command runs it: it fails (non-zero exit) unless the round placed at least one
//! object and the run directory holds a model that loads with the round's node counts.

use std::path::PathBuf;

use lgdm_gdm::Gdm;
use lgdm_sim::grasping::source::AnalyticSource;
use lgdm_sim::recognition::encoder::GoodEncoder;
use lgdm_sim::recognition::model::{MODEL_FILE, MODEL_LABELS_FILE, ModelRecord};
use lgdm_sim::run::job::{Output, PickPlaceJob, PickPlaceSetup};
use lgdm_sim::run::report::summary_text;
use lgdm_sim::run::results::RESULTS_FILE;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let tmp = tempfile::tempdir()?;
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| tmp.path().join("pick-place"), PathBuf::from);
    let setup = PickPlaceSetup {
        rounds: Some(1),
        seed: 3,
        out: Some(Output::new(&out)),
        ..PickPlaceSetup::default()
    };
    let job = PickPlaceJob::prepare(setup)?;
    let results = job.run(&mut AnalyticSource::new(), Box::new(GoodEncoder), |p| {
        eprintln!("{} {}/{}", p.stage, p.done, p.total)
    })?;
    print!("{}", summary_text(&results));

    // What the round left behind: results.json and the model with its record.
    let placed = results.summary.placement_success_rate.successes;
    if placed == 0 {
        return Err("the round placed no object".into());
    }
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(RESULTS_FILE))?)?;
    if written["summary"]["attempts"] != results.summary.attempts {
        return Err("results.json does not hold the run's attempts".into());
    }
    let model = Gdm::load(&out.join(MODEL_FILE))?;
    let record: ModelRecord =
        serde_json::from_str(&std::fs::read_to_string(out.join(MODEL_LABELS_FILE))?)?;
    let last = results.recognition.as_ref().and_then(|r| r.memory.last());
    if last.map(|m| m.episodic_nodes) != Some(model.episodic().len()) || record.encoder != "good" {
        return Err("the saved model is not the one the round learnt".into());
    }
    println!(
        "placed {placed} of {} objects; {} wrote a model of {} G-EM nodes ({} categories named)",
        results.rounds[0].objects.len(),
        out.display(),
        model.episodic().len(),
        record.categories.len()
    );
    Ok(())
}
