//! Issue 43, item 1: irregular shapes land. A thin stick or slab lying still in the basket can
//! tremble in the solver (1 cm/s, 1 rad/s) for as long as it is watched while its pose stays put;
//! the placement watches such an object for `REST_WINDOW_S` and judges it by how far it moved,
//! so these count as placed (before: each judged "dropped outside", though inside and still).

use lgdm_sim::datagen::object_sets::lay_out_irregular;
use lgdm_sim::grasping::attempt::{FailureReason, REST_DRIFT_M, REST_TURN_RAD};
use lgdm_sim::grasping::source::builtin_source;
use lgdm_sim::run::config::SimConfig;
use lgdm_sim::run::job::{GraspJob, GraspSetup};
use lgdm_sim::run::objects::ObjectSource;
use lgdm_sim::tasks::scenario::Scenario;

#[test]
fn trembling_sticks_and_slabs_are_judged_placed_when_they_stay_put() {
    let tmp = tempfile::tempdir().unwrap();
    let all = tmp.path().join("all");
    lay_out_irregular(0, &all).unwrap();
    // The validation set's objects that trembled in the basket before the window.
    let dir = tmp.path().join("some");
    for (family, name) in [
        ("slab", "slab_05"),
        ("stick", "stick_01"),
        ("stick", "stick_04"),
    ] {
        std::fs::create_dir_all(dir.join(family)).unwrap();
        let file = format!("{name}.obj");
        std::fs::copy(all.join(family).join(&file), dir.join(family).join(&file)).unwrap();
    }
    let setup = GraspSetup {
        scenario: Scenario::Isolated,
        rounds: 6,
        seed: 0,
        objects: Some(ObjectSource::Meshes {
            dir: dir.clone(),
            units: lgdm_pointcloud::import::MeshUnits::parse(&["m"]).unwrap(),
        }),
        config: SimConfig::default(),
        ..GraspSetup::default()
    };
    let r = GraspJob::prepare(setup)
        .unwrap()
        .run(builtin_source("analytic", 0).unwrap().as_mut(), |_| {})
        .unwrap();
    let grasped: Vec<_> = r.attempts.iter().filter(|a| a.grasp_success).collect();
    assert!(grasped.len() >= 5, "{:?}", r.attempts);
    let mut watched = 0;
    for a in &grasped {
        assert!(a.placement_success, "{a:?}");
        if let Some([drift, turn]) = a.measured.placed_drift {
            watched += 1;
            assert!(drift < REST_DRIFT_M && turn < REST_TURN_RAD, "{a:?}");
        }
    }
    assert!(
        r.attempts
            .iter()
            .all(|a| a.reason != Some(FailureReason::DroppedOutside)),
        "{:?}",
        r.attempts
    );
    // The window is what judged them: without it these would have failed.
    assert!(watched >= 2, "{watched} of {} watched", grasped.len());
}
