//! A run stopped between rounds and resumed ends exactly as a run never stopped: the same
//! results (wall-clock fields aside), the same model and the same recordings, byte for byte;
//! the finished rounds' files are kept as they were written, and the checkpoint is gone at the
//! end (issue 22, row 10). The stop is a panic out of the progress callback right after the
//! first round's checkpoint — what a kill then leaves on disk, made deterministic.

use std::path::{Path, PathBuf};

use lgdm_sim::grasping::source::builtin_source;
use lgdm_sim::recognition::encoder::GoodEncoder;
use lgdm_sim::run::job::{
    GraspJob, GraspSetup, JobKind, JobRecord, Output, PickPlaceJob, PickPlaceSetup,
};
use lgdm_sim::run::record::RecordConfig;
use lgdm_sim::run::run_dir::{PROGRESS_DIR, PROGRESS_FILE};
use lgdm_sim::tasks::scenario::Scenario;

/// `value` without the wall-clock fields (every key named `wall`).
fn without_wall(value: &mut serde_json::Value) {
    match value {
        serde_json::Value::Object(map) => {
            map.remove("wall");
            map.values_mut().for_each(without_wall);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(without_wall),
        _ => {}
    }
}

fn results(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    without_wall(&mut v);
    v
}

/// Every file under `dir` but results.json and summary.txt (wall times), with its bytes.
fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else if !["results.json", "summary.txt"]
                .contains(&p.file_name().unwrap().to_str().unwrap())
            {
                out.push((
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// Runs `play`, stopping it (a panic) at the first progress report after round 1.
fn stopped(play: impl FnOnce(&mut dyn FnMut(lgdm_base::Progress))) {
    let stop = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        play(&mut |p| {
            if p.stage == "rounds" && p.done == 1 {
                panic!("stopped after round 1");
            }
        })
    }));
    assert!(stop.is_err(), "the run was not stopped");
}

fn assert_same_runs(straight: &Path, resumed: &Path) {
    assert_eq!(results(straight), results(resumed));
    assert_eq!(files(straight), files(resumed));
    assert!(!resumed.join(PROGRESS_FILE).exists() && !resumed.join(PROGRESS_DIR).exists());
}

#[test]
fn a_resumed_pick_place_run_equals_one_never_stopped() {
    let tmp = tempfile::tempdir().unwrap();
    let setup = |out: &Path| PickPlaceSetup {
        rounds: Some(3),
        seed: 1,
        set_size: 5,
        record: Some(RecordConfig::default()),
        out: Some(Output::new(out)),
        ..PickPlaceSetup::default()
    };
    let (a, b) = (tmp.path().join("straight"), tmp.path().join("resumed"));
    let analytic = || builtin_source("analytic", 1).unwrap();
    PickPlaceJob::prepare(setup(&a))
        .unwrap()
        .run(analytic().as_mut(), Box::new(GoodEncoder), |_| {})
        .unwrap();
    stopped(|progress| {
        let job = PickPlaceJob::prepare(setup(&b)).unwrap();
        let _ = job.run(analytic().as_mut(), Box::new(GoodEncoder), progress);
    });
    assert!(b.join(PROGRESS_FILE).is_file() && !b.join("results.json").exists());
    let round_0 = std::fs::read(b.join("rounds/round-0000.mcap")).unwrap();
    // Resume as the binary does: the job again from its record.
    let record = JobRecord::read(&b).unwrap();
    assert_eq!(record.grasp_source, "analytic");
    let JobKind::PickPlace(mut again) = record.job else {
        panic!("a pick-place record")
    };
    again.out = Some(Output::new(&b));
    PickPlaceJob::prepare(*again)
        .unwrap()
        .resume(analytic().as_mut(), Box::new(GoodEncoder), |_| {})
        .unwrap();
    assert_eq!(
        std::fs::read(b.join("rounds/round-0000.mcap")).unwrap(),
        round_0
    );
    assert_same_runs(&a, &b);
    // A finished run has nothing to resume.
    let job = PickPlaceJob::prepare(setup(&b)).unwrap();
    let e = job
        .resume(analytic().as_mut(), Box::new(GoodEncoder), |_| {})
        .unwrap_err();
    assert!(e.to_string().contains("finished"), "{e}");
}

/// The random source's stream is part of the state: a resumed random run draws what the
/// straight one drew.
#[test]
fn a_resumed_random_grasp_run_equals_one_never_stopped() {
    let tmp = tempfile::tempdir().unwrap();
    let setup = |out: &Path| GraspSetup {
        scenario: Scenario::Scattered,
        rounds: 3,
        seed: 2,
        out: Some(Output::new(out)),
        ..GraspSetup::default()
    };
    let (a, b) = (tmp.path().join("straight"), tmp.path().join("resumed"));
    let random = || builtin_source("random", 2).unwrap();
    GraspJob::prepare(setup(&a))
        .unwrap()
        .run(random().as_mut(), |_| {})
        .unwrap();
    stopped(|progress| {
        let job = GraspJob::prepare(setup(&b)).unwrap();
        let _ = job.run(random().as_mut(), progress);
    });
    let JobKind::Grasp(mut again) = JobRecord::read(&b).unwrap().job else {
        panic!("a grasp record")
    };
    again.out = Some(Output::new(&b));
    let job = GraspJob::prepare(*again).unwrap();
    // Another source than the record's is refused.
    let e = job
        .resume(builtin_source("analytic", 2).unwrap().as_mut(), |_| {})
        .unwrap_err();
    assert!(e.to_string().contains("random"), "{e}");
    job.resume(random().as_mut(), |_| {}).unwrap();
    assert_same_runs(&a, &b);
}
