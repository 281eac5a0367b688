//! Within a round the robot does not try again a grasp that failed (`[scenario]
//! failed_grasp_radius_m`, `failed_grasp_angle_deg`): on the isolated table and on a cluttered
//! one, a source that proposes the same grasp every time gets it tried once a round with the
//! memory on, and again and again with it off (radius 0); `summary.repeats` counts the attempts
//! that repeated a failed grasp, and `proposals.repeat_skipped` the candidates skipped.

use std::path::Path;

use lgdm_pointcloud::grasp::decode::DecodedGrasp;
use lgdm_pointcloud::mesh::Mesh;
use lgdm_sim::grasping::source::FixedSource;
use lgdm_sim::run::config::SimConfig;
use lgdm_sim::run::job::{GraspJob, GraspSetup};
use lgdm_sim::run::objects::ObjectSource;
use lgdm_sim::run::results::{RoundEnd, RunResults, count_repeats};
use lgdm_sim::tasks::scenario::Scenario;

/// Cans of 6 cm across and 10 cm high, 50 kg each (too heavy to lift: every grasp on one fails
/// in the lift, where it was planned), in `dir`: one per colour given.
fn heavy_cans(dir: &Path, colours: &[(&str, [u8; 3])]) {
    let mut sidecar = String::from("[all]\nunit = \"m\"\n");
    for (name, colour) in colours {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        let can = Mesh::lathe(
            &[[0.0, 0.0], [0.03, 0.0], [0.03, 0.1], [0.0, 0.1]],
            32,
            *colour,
        );
        let file = format!("{name}/{name}_01.obj");
        std::fs::write(dir.join(&file), can.to_obj()).unwrap();
        sidecar += &format!("\n[files.\"{file}\"]\nmass_kg = 50.0\n");
    }
    std::fs::write(dir.join("objects.toml"), sidecar).unwrap();
}

/// The same grasp `copies` times: across the crop's centre (the object's), 9 cm open.
fn the_same_grasp(copies: usize) -> FixedSource {
    let g = DecodedGrasp {
        center_px: [112.0, 112.0],
        angle: 0.3,
        width_px: 90.0,
        jaw_px: 20.0,
        quality: 0.9,
    };
    FixedSource(vec![g; copies])
}

fn run(
    dir: &Path,
    scenario: Scenario,
    rounds: usize,
    copies: usize,
    memory_on: bool,
) -> RunResults {
    let mut config = SimConfig::default();
    config.scenario.clutter_objects = 2;
    if !memory_on {
        config.scenario.failed_grasp_radius_m = 0.0;
    }
    let setup = GraspSetup {
        scenario,
        rounds,
        seed: 3,
        objects: Some(ObjectSource::Meshes {
            dir: dir.to_path_buf(),
            units: lgdm_pointcloud::import::MeshUnits::parse(&["m"]).unwrap(),
        }),
        config,
        ..GraspSetup::default()
    };
    let mut source = the_same_grasp(copies);
    GraspJob::prepare(setup)
        .unwrap()
        .run(&mut source, |_| {})
        .unwrap()
}

/// Isolated: three ranked copies of one grasp. With the memory on, the first fails and the two
/// copies are skipped; off, all three are tried and fail.
#[test]
fn an_isolated_object_is_not_tried_again_where_a_grasp_failed() {
    let tmp = tempfile::tempdir().unwrap();
    heavy_cans(tmp.path(), &[("can", [40, 90, 160])]);
    let on = run(tmp.path(), Scenario::Isolated, 2, 3, true);
    assert_eq!(on.attempts.len(), 2, "one attempt a round: {:?}", on.rounds);
    for a in &on.attempts {
        assert!(a.grasp.is_some() && !a.grasp_success, "{a:?}");
        assert_eq!(a.proposals.repeat_skipped, 2, "{:?}", a.proposals);
    }
    assert_eq!(on.summary.proposals.repeat_skipped, 4);
    assert_eq!(on.summary.repeats.attempts, 0);

    let off = run(tmp.path(), Scenario::Isolated, 2, 3, false);
    assert_eq!(off.attempts.len(), 6, "three attempts a round");
    assert!(off.attempts.iter().all(|a| !a.grasp_success));
    assert_eq!(off.summary.proposals.repeat_skipped, 0);
    // Judged at the default memory: the second and third of each round repeat the first.
    assert_eq!(
        (
            off.summary.repeats.attempts,
            off.summary.repeats.failed_again
        ),
        (4, 4)
    );
    // The tries in a round are numbered as they were made.
    let tries: Vec<usize> = off.attempts.iter().map(|a| a.try_in_round).collect();
    assert_eq!(tries, [0, 1, 2, 0, 1, 2]);
}

/// Cluttered: two heavy cans apart on the table, one grasp proposed on each. With the memory on, each is tried once, then
/// the look finds only failed grasps and the round ends; no attempt repeats a failed grasp,
/// judged with the memory's radius and angle. Off, the third attempt in a row (the
/// `k`-th best after `k` failures, else the last) repeats one.
#[test]
fn a_cluttered_table_is_not_tried_again_where_a_grasp_failed() {
    let tmp = tempfile::tempdir().unwrap();
    heavy_cans(
        tmp.path(),
        &[("can", [40, 90, 160]), ("tin", [200, 60, 40])],
    );
    let on = run(tmp.path(), Scenario::Scattered, 1, 1, true);
    let tried: Vec<bool> = on.attempts.iter().map(|a| a.grasp.is_some()).collect();
    assert_eq!(tried, [true, true, false], "{:?}", on.attempts);
    assert_eq!(on.rounds[0].ended_by, RoundEnd::NoGrasp);
    assert_eq!(on.attempts[2].proposals.repeat_skipped, 2);
    let radius = on.config.scenario.failed_grasp_radius_m;
    let angle = on.config.scenario.failed_grasp_angle_deg;
    assert_eq!(count_repeats(&on.attempts, radius, angle).attempts, 0);
    assert_eq!(on.summary.repeats.attempts, 0);

    let off = run(tmp.path(), Scenario::Scattered, 1, 1, false);
    assert_eq!(off.attempts.len(), 3, "{:?}", off.rounds);
    assert!(off.attempts.iter().all(|a| a.grasp.is_some()));
    assert_eq!(off.rounds[0].ended_by, RoundEnd::ConsecutiveFailures);
    assert_eq!(
        (
            off.summary.repeats.attempts,
            off.summary.repeats.failed_again
        ),
        (1, 1)
    );
}
