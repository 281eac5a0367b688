//! A recorded round opens as MCAP with foxglove's schemas: every topic of the recording is on a
//! `protobuf` channel of its `foxglove.*` schema, the messages decode with foxglove's types
//! (`/tf` holds every arm link, the palm, both fingers and the object; the scene draws the
//! object's mesh in its frame; images and calibration match the cameras), log times are sim
//! times and never go back, and the same seed gives the same bytes — while the run's results
//! are exactly those of a run without recording; each arm contact an attempt avoided is an
//! event.
//!
//! Run in release (`cargo test -p lgdm-sim --release --test record`).

use std::collections::BTreeMap;

use foxglove::messages::{CameraCalibration, FrameTransforms, Log, RawImage, SceneUpdate};
use lgdm_pointcloud::objects::{ObjectModel, procedural_library};
use lgdm_sim::grasping::source::builtin_source;
use lgdm_sim::run::record::{RecordConfig, RoundRecorder, RoundRecording};
use lgdm_sim::run::results::RunResults;
use lgdm_sim::run::runner::run_trials;
use lgdm_sim::run::spec::RunSpec;
use lgdm_sim::tasks::scenario::Scenario;
use prost::Message as _;

fn library() -> Vec<ObjectModel> {
    procedural_library(&["can", "book"], 1, 0).unwrap()
}

fn recorded(rounds: usize, seed: u64) -> (RunResults, Vec<RoundRecording>) {
    let library = library();
    let spec = RunSpec::new(Scenario::Isolated, rounds, seed);
    let mut source = builtin_source("analytic", seed).unwrap();
    let mut sink: Vec<RoundRecording> = Vec::new();
    let config = RecordConfig::default();
    let results = run_recorded(&spec, &library, source.as_mut(), &config, &mut sink).unwrap();
    (results, sink)
}

/// [`run_trials`] with the rounds `config` selects recorded into `sink`.
fn run_recorded(
    spec: &RunSpec,
    library: &[lgdm_pointcloud::objects::ObjectModel],
    source: &mut dyn lgdm_sim::grasping::source::GraspSource,
    config: &RecordConfig,
    sink: &mut Vec<RoundRecording>,
) -> Result<RunResults, lgdm_sim::run::error::SimError> {
    let mut recorder = RoundRecorder::new(config, sink, spec.config.cameras.clone())?;
    run_trials(spec, library, source, &mut recorder, |_| {})
}

/// The attempts without their wall-clock times.
fn deterministic(r: &RunResults) -> Vec<lgdm_sim::run::results::AttemptRecord> {
    r.attempts
        .iter()
        .map(|a| lgdm_sim::run::results::AttemptRecord {
            wall: Default::default(),
            ..a.clone()
        })
        .collect()
}

/// Every message of a recording: (topic, schema name, schema encoding, message encoding,
/// log time, publish time, data).
type Row = (String, String, String, String, u64, u64, Vec<u8>);

fn messages(mcap: &[u8]) -> Vec<Row> {
    mcap::MessageStream::new(mcap)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            (
                m.channel.topic.clone(),
                schema.name.clone(),
                schema.encoding.clone(),
                m.channel.message_encoding.clone(),
                m.log_time,
                m.publish_time,
                m.data.into_owned(),
            )
        })
        .collect()
}

fn on<'a>(rows: &'a [Row], topic: &str) -> Vec<&'a Row> {
    rows.iter().filter(|r| r.0 == topic).collect()
}

#[test]
fn recorded_rounds_open_with_foxglove_schemas_and_are_reproducible() {
    let (results, rounds) = recorded(2, 0);
    assert_eq!(rounds.len(), 2);
    assert_eq!(
        rounds.iter().map(|r| r.round).collect::<Vec<_>>(),
        vec![0, 1]
    );

    for (recording, round) in rounds.iter().zip(&results.rounds) {
        let summary = mcap::read::Summary::read(&recording.mcap)
            .unwrap()
            .expect("a summary section");
        // Every channel, with or without messages, names its foxglove schema.
        let channels: BTreeMap<String, (String, String, String)> = summary
            .channels
            .values()
            .map(|c| {
                let s = c.schema.as_ref().unwrap();
                (
                    c.topic.clone(),
                    (
                        s.name.clone(),
                        s.encoding.clone(),
                        c.message_encoding.clone(),
                    ),
                )
            })
            .collect();
        let expect = |topic: &str, schema: &str| {
            let (name, encoding, message_encoding) = channels
                .get(topic)
                .unwrap_or_else(|| panic!("no channel {topic}: {channels:?}"));
            assert_eq!(name, schema, "{topic}");
            assert_eq!(encoding, "protobuf", "{topic}");
            assert_eq!(message_encoding, "protobuf", "{topic}");
        };
        expect("/tf", "foxglove.FrameTransforms");
        expect("/scene", "foxglove.SceneUpdate");
        expect("/grasp", "foxglove.SceneUpdate");
        expect("/events", "foxglove.Log");
        for camera in ["overview", "closeup", "basket"] {
            expect(&format!("/camera/{camera}/rgb"), "foxglove.RawImage");
            expect(&format!("/camera/{camera}/depth"), "foxglove.RawImage");
            expect(
                &format!("/camera/{camera}/calibration"),
                "foxglove.CameraCalibration",
            );
        }
        let meta = mcap::read::metadata(&recording.mcap, &summary.metadata_indexes[0]).unwrap();
        assert_eq!(meta.name, "lgdm.round");
        assert_eq!(meta.metadata["round"], round.round.to_string());
        assert_eq!(meta.metadata["grasp_source"], "analytic");

        let rows = messages(&recording.mcap);
        // Log times are sim times: never decreasing, publish time = log time, and the last one
        // is the round's end, within the round's simulated seconds of the start.
        let mut last = 0;
        for r in &rows {
            assert!(r.4 >= last, "{} at {} after {last}", r.0, r.4);
            assert_eq!(r.4, r.5);
            last = r.4;
        }
        assert!(last as f64 * 1e-9 >= round.sim_time_s, "{last}");

        // /tf: every arm link, the palm, both fingers and the object.
        let object = format!("object/{}", round.objects[0]);
        let tf = on(&rows, "/tf");
        let full = tf
            .iter()
            .map(|r| FrameTransforms::decode(r.6.as_slice()).unwrap())
            .rfind(|m| m.transforms.len() > 1)
            .unwrap();
        let children: Vec<&str> = full
            .transforms
            .iter()
            .map(|t| t.child_frame_id.as_str())
            .collect();
        for frame in [
            "arm/link_1",
            "arm/link_2",
            "arm/link_3",
            "arm/link_4",
            "arm/link_5",
            "arm/link_6",
            "gripper/palm",
            "gripper/finger_l",
            "gripper/finger_r",
        ] {
            assert!(children.contains(&frame), "{frame} missing: {children:?}");
        }
        assert!(full.transforms.iter().all(|t| t.parent_frame_id == "world"));
        // The object is on /tf while it lives (a placed object is removed at the end).
        let with_object = tf
            .iter()
            .map(|r| FrameTransforms::decode(r.6.as_slice()).unwrap())
            .filter(|m| m.transforms.iter().any(|t| t.child_frame_id == object))
            .count();
        assert!(with_object > 10, "{object} on {with_object} /tf messages");
        // About 30 Hz of sim time.
        let rate = tf.len() as f64 / (last as f64 * 1e-9);
        assert!((25.0..45.0).contains(&rate), "{rate} /tf messages per s");

        // /scene: the object's mesh in its frame, the links drawn as shapes.
        let scenes: Vec<SceneUpdate> = on(&rows, "/scene")
            .iter()
            .map(|r| SceneUpdate::decode(r.6.as_slice()).unwrap())
            .collect();
        let entities: Vec<_> = scenes.iter().flat_map(|s| s.entities.iter()).collect();
        let mesh = entities
            .iter()
            .find(|e| e.id == object)
            .unwrap_or_else(|| panic!("no entity {object}"));
        assert!(mesh.frame_locked && mesh.frame_id == object);
        assert!(mesh.triangles[0].points.len() >= 3 * 12);
        assert_eq!(
            mesh.triangles[0].points.len(),
            mesh.triangles[0].colors.len()
        );
        let link = entities.iter().find(|e| e.id == "arm/link_2").unwrap();
        assert!(!link.cylinders.is_empty() && link.frame_locked);
        assert!(
            entities
                .iter()
                .any(|e| e.id == "scenery" && e.cubes.len() >= 6)
        );

        // Cameras: the overview's image and calibration.
        let rgb = RawImage::decode(on(&rows, "/camera/overview/rgb")[0].6.as_slice()).unwrap();
        assert_eq!(
            (rgb.width, rgb.height, rgb.encoding.as_str()),
            (224, 224, "rgb8")
        );
        assert_eq!(rgb.data.len(), 3 * 224 * 224);
        assert_eq!(rgb.frame_id, "camera/overview");
        let depth = RawImage::decode(on(&rows, "/camera/overview/depth")[0].6.as_slice()).unwrap();
        assert_eq!(depth.encoding, "32FC1");
        let centre = 4 * (112 * 224 + 112);
        let d = f32::from_le_bytes(depth.data[centre..centre + 4].try_into().unwrap());
        assert!((0.9..1.2).contains(&d), "depth at the centre {d} m");
        let calib =
            CameraCalibration::decode(on(&rows, "/camera/overview/calibration")[0].6.as_slice())
                .unwrap();
        assert!((calib.k[0] - 307.7).abs() < 0.1, "{:?}", calib.k);
        assert_eq!(calib.p.len(), 12);
        let closeup = RawImage::decode(on(&rows, "/camera/closeup/rgb")[0].6.as_slice()).unwrap();
        assert_eq!((closeup.width, closeup.height), (640, 480));

        // /grasp: planned, then coloured by the outcome; /events: start and end of attempts.
        let attempts: Vec<_> = results
            .attempts
            .iter()
            .filter(|a| a.round == round.round)
            .collect();
        let tried = attempts.iter().filter(|a| a.grasp.is_some()).count();
        let grasps: Vec<SceneUpdate> = on(&rows, "/grasp")
            .iter()
            .map(|r| SceneUpdate::decode(r.6.as_slice()).unwrap())
            .collect();
        assert_eq!(grasps.len(), 2 * tried);
        if let Some(last_grasp) = grasps.last() {
            let e = &last_grasp.entities[0];
            assert_eq!(e.cubes.len(), 2);
            let outcome = e.metadata.iter().find(|kv| kv.key == "outcome").unwrap();
            assert_ne!(outcome.value, "planned");
        }
        let events: Vec<String> = on(&rows, "/events")
            .iter()
            .map(|r| Log::decode(r.6.as_slice()).unwrap().message)
            .collect();
        assert_eq!(
            events
                .iter()
                .filter(|m| m.starts_with("attempt end"))
                .count(),
            tried,
            "{events:?}"
        );
        assert!(events.last().unwrap().contains("end"), "{events:?}");

        // The storyboard: a row per attempt.
        assert!(recording.storyboard.width >= 3 * 224);
        assert!(recording.storyboard.height >= attempts.len() * 224);
    }

    // Same seed, same bytes; and the results are those of a run without recording.
    let (again, rounds_again) = recorded(2, 0);
    for (a, b) in rounds.iter().zip(&rounds_again) {
        assert!(a.mcap == b.mcap, "round {} MCAP bytes differ", a.round);
        assert_eq!(a.storyboard, b.storyboard);
    }
    assert_eq!(deterministic(&results), deterministic(&again));
    let plain = {
        let spec = RunSpec::new(Scenario::Isolated, 2, 0);
        let mut source = builtin_source("analytic", 0).unwrap();
        run_trials(&spec, &library(), source.as_mut(), &mut (), |_| {}).unwrap()
    };
    assert_eq!(deterministic(&results), deterministic(&plain));
}

#[test]
fn first_rounds_limits_what_is_recorded() {
    let library = library();
    let spec = RunSpec::new(Scenario::Isolated, 2, 5);
    let mut source = builtin_source("random", 5).unwrap();
    let mut sink: Vec<RoundRecording> = Vec::new();
    let config = RecordConfig {
        first_rounds: Some(1),
        ..RecordConfig::default()
    };
    run_recorded(&spec, &library, source.as_mut(), &config, &mut sink).unwrap();
    assert_eq!(sink.len(), 1);
    assert_eq!(sink[0].file_stem(), "round-0000");
    let bad = RecordConfig {
        tf_rate_hz: f64::NAN,
        ..RecordConfig::default()
    };
    let err = run_recorded(&spec, &library, source.as_mut(), &bad, &mut sink).unwrap_err();
    assert!(err.to_string().contains("tf_rate_hz"), "{err}");
}

/// A pick-and-place recording shows what the robot made of each object: a label on `/labels`
/// in the object's frame (so it travels with it), coloured by how recognition went, with the
/// true and guessed labels as metadata, deleted when the object goes.
#[test]
fn pick_place_recordings_label_every_recognised_object() {
    use lgdm_sim::recognition::config::RecognitionConfig;
    use lgdm_sim::recognition::labels::Labels;
    use lgdm_sim::recognition::recognizer::Recognizer;
    let library = library();
    let spec = RunSpec::new(Scenario::Isolated, 3, 0);
    let mut source = builtin_source("analytic", 0).unwrap();
    let mut recognizer = Recognizer::empty(
        RecognitionConfig::default(),
        Labels::of_objects(&library),
        0,
    )
    .unwrap();
    let mut sink: Vec<RoundRecording> = Vec::new();
    let config = RecordConfig::default();
    let mut recorder = RoundRecorder::new(&config, &mut sink, spec.config.cameras.clone()).unwrap();
    let results = lgdm_sim::run::runner::run_pick_place(
        &spec,
        &library,
        source.as_mut(),
        &mut recognizer,
        &mut recorder,
        |_| {},
    )
    .unwrap();
    assert_eq!(sink.len(), 3);
    let mut labels_seen = 0;
    for (recording, round) in sink.iter().zip(&results.rounds) {
        let rows = messages(&recording.mcap);
        let updates: Vec<SceneUpdate> = on(&rows, "/labels")
            .iter()
            .map(|r| {
                assert_eq!(r.1, "foxglove.SceneUpdate");
                SceneUpdate::decode(r.6.as_slice()).unwrap()
            })
            .collect();
        let object = format!("object/{}", round.objects[0]);
        let recognition = results
            .attempts
            .iter()
            .filter(|a| a.round == round.round)
            .find_map(|a| a.recognition.clone())
            .expect("the round's object was recognised");
        let label = updates
            .iter()
            .flat_map(|u| u.entities.iter())
            .find(|e| e.id == format!("label/{object}"))
            .unwrap_or_else(|| panic!("no label for {object}: {updates:?}"));
        labels_seen += 1;
        assert!(label.frame_locked && label.frame_id == object);
        let text = &label.texts[0];
        assert!(text.billboard && text.text.starts_with(&recognition.true_instance));
        let meta: BTreeMap<&str, &str> = label
            .metadata
            .iter()
            .map(|kv| (kv.key.as_str(), kv.value.as_str()))
            .collect();
        assert_eq!(meta["true_instance"], recognition.true_instance);
        assert_eq!(meta["teacher"], recognition.teacher.to_string());
        assert_eq!(meta["known"], recognition.guess.known.to_string());
        // Amber for "I don't know this" (the first round, from an empty model), green when known
        // and right.
        let color = text.color.as_ref().unwrap();
        match (recognition.guess.known, recognition.teacher) {
            (false, _) => assert!(color.r > 0.9 && color.g > 0.5 && color.b < 0.2, "{color:?}"),
            (true, false) => assert!(color.g > 0.7 && color.r < 0.3, "{color:?}"),
            (true, true) => assert!(color.r > 0.8 && color.g < 0.3, "{color:?}"),
        }
        if round.round == 0 {
            assert!(!recognition.guess.known && text.text.contains("I don't know this"));
        }
        // A placed object leaves the table, and its label with it.
        if round.placed > 0 {
            let deleted = updates
                .iter()
                .flat_map(|u| u.deletions.iter())
                .any(|d| d.id == label.id);
            assert!(deleted, "{} not deleted", label.id);
        }
    }
    assert_eq!(labels_seen, 3);
}

/// Each contact an attempt avoided is an event on `/events`: with a bin in the carry's way
/// (`docs/results/bin-in-the-way.toml`), every attempt whose planned moves would have swept
/// something through it logs what, once per contact.
#[test]
fn avoided_arm_contacts_are_events() {
    let mut spec = RunSpec::new(Scenario::Isolated, 3, 0);
    let mut bin = spec.config.world.baskets[0].clone();
    let top = spec.config.world.table.top_z_m();
    bin.floor_center_m = [0.58, -0.4, top + 0.01];
    bin.inner_size_m = [0.15, 0.15];
    bin.wall_height_m = 0.25;
    spec.config.world.baskets.push(bin);
    let mut source = builtin_source("analytic", 0).unwrap();
    let mut sink: Vec<RoundRecording> = Vec::new();
    let results = run_recorded(
        &spec,
        &library(),
        source.as_mut(),
        &RecordConfig::default(),
        &mut sink,
    )
    .unwrap();
    let expected: Vec<String> = results
        .attempts
        .iter()
        .flat_map(|a| &a.measured.avoided_contacts)
        .map(|c| format!("arm contact avoided: {c}"))
        .collect();
    assert!(!expected.is_empty(), "{:?}", results.attempts);
    assert!(
        expected.iter().all(|e| e.contains("basket 2")),
        "{expected:?}"
    );
    let logged: Vec<String> = sink
        .iter()
        .flat_map(|round| {
            on(&messages(&round.mcap), "/events")
                .into_iter()
                .cloned()
                .collect::<Vec<_>>()
        })
        .map(|r| Log::decode(r.6.as_slice()).unwrap().message)
        .filter(|m| m.starts_with("arm contact"))
        .collect();
    assert_eq!(logged, expected);
}
