//! Invariant: a checkpoint reproduces the model exactly (same bytes, same predictions); saving is
//! atomic (no temporary file left, an existing file is replaced whole); truncated, corrupted,
//! wrong-version or foreign files give typed errors, never a panic.

use lgdm_gdm::checkpoint::{HEADER_LEN, VERSION};
use lgdm_gdm::{CheckpointError, Gdm, GdmConfig, Metric, PredictOptions, Sample};

fn rows() -> Vec<(Vec<f32>, u64, u32)> {
    (0..200u32)
        .map(|i| {
            let c = i / 50;
            let t = (i % 10) as f32;
            (
                vec![
                    c as f32 * 0.5 + 0.03 * t,
                    ((i * 7) % 11) as f32 * 0.02,
                    0.1 * c as f32,
                ],
                (i / 10) as u64,
                c,
            )
        })
        .collect()
}

fn model(metric: Metric) -> Gdm {
    let rows = rows();
    let samples: Vec<Sample> = rows
        .iter()
        .map(|(x, s, c)| Sample::labelled(x, *s, *c * 10, *c))
        .collect();
    let config = GdmConfig {
        metric,
        ..GdmConfig::paper_batch()
    };
    let mut gdm = Gdm::new(config, 3).unwrap();
    for _ in 0..2 {
        gdm.train(&samples).unwrap();
        gdm.end_episode();
        gdm.replay().unwrap();
    }
    gdm.train(&samples[..15]).unwrap(); // leave a sequence open
    gdm
}

#[test]
fn round_trip_reproduces_bytes_and_predictions() {
    for metric in [Metric::Manhattan, Metric::Mahalanobis, Metric::Cosine] {
        let gdm = model(metric);
        let bytes = gdm.to_bytes();
        assert_eq!(&bytes[..8], b"LGDMCKPT");
        assert_eq!(bytes.len(), gdm.size_bytes());
        let back = Gdm::from_bytes(&bytes).unwrap();
        assert_eq!(back, gdm);
        assert_eq!(back.to_bytes(), bytes);
        let rows = rows();
        let samples: Vec<Sample> = rows
            .iter()
            .map(|(x, s, _)| Sample::unlabelled(x, *s))
            .collect();
        let opts = PredictOptions::default();
        assert_eq!(
            back.predict(&samples, opts).unwrap(),
            gdm.predict(&samples, opts).unwrap()
        );
        // Training on after a round trip continues identically (open sequence included).
        let (mut a, mut b) = (gdm.clone(), back);
        a.train(&samples[15..40]).unwrap();
        b.train(&samples[15..40]).unwrap();
        assert_eq!(a.to_bytes(), b.to_bytes());
    }
}

#[test]
fn save_is_atomic_and_load_reads_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.lgdm");
    std::fs::write(&path, b"old content").unwrap();
    let gdm = model(Metric::Manhattan);
    gdm.save(&path).unwrap();
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(
        names,
        vec!["model.lgdm".to_string()],
        "no temporary file may remain"
    );
    assert_eq!(std::fs::read(&path).unwrap(), gdm.to_bytes());
    assert_eq!(Gdm::load(&path).unwrap(), gdm);
    let missing = dir.path().join("missing.lgdm");
    assert!(matches!(Gdm::load(&missing), Err(CheckpointError::Io(_))));
    let no_dir = dir.path().join("no/such/dir/model.lgdm");
    assert!(matches!(gdm.save(&no_dir), Err(CheckpointError::Io(_))));
}

#[test]
fn truncated_files_are_reported_as_truncated() {
    let bytes = model(Metric::Manhattan).to_bytes();
    for len in [
        0,
        4,
        8,
        12,
        HEADER_LEN - 1,
        HEADER_LEN,
        HEADER_LEN + 10,
        bytes.len() - 1,
    ] {
        match Gdm::from_bytes(&bytes[..len]) {
            Err(CheckpointError::Truncated { expected, found }) => {
                assert_eq!(found, len as u64);
                assert!(expected > found);
            }
            other => panic!("length {len}: expected Truncated, got {other:?}"),
        }
    }
}

#[test]
fn corrupted_payloads_fail_the_checksum() {
    let bytes = model(Metric::Manhattan).to_bytes();
    for at in [
        HEADER_LEN,
        HEADER_LEN + 100,
        bytes.len() / 2,
        bytes.len() - 1,
    ] {
        let mut bad = bytes.clone();
        bad[at] ^= 0x40;
        assert!(
            matches!(Gdm::from_bytes(&bad), Err(CheckpointError::Checksum { .. })),
            "flipped byte {at}"
        );
    }
    let mut bad = bytes.clone();
    bad[20] ^= 1; // the stored checksum itself
    assert!(matches!(
        Gdm::from_bytes(&bad),
        Err(CheckpointError::Checksum { .. })
    ));
}

#[test]
fn wrong_version_magic_and_trailing_bytes_are_reported() {
    let bytes = model(Metric::Manhattan).to_bytes();
    let mut v2 = bytes.clone();
    v2[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
    match Gdm::from_bytes(&v2) {
        Err(CheckpointError::Version { found, supported }) => {
            assert_eq!((found, supported), (VERSION + 1, VERSION));
        }
        other => panic!("expected Version, got {other:?}"),
    }
    let mut foreign = bytes.clone();
    foreign[0] = b'X';
    assert!(matches!(
        Gdm::from_bytes(&foreign),
        Err(CheckpointError::BadMagic)
    ));
    assert!(matches!(
        Gdm::from_bytes(b"PK\x03\x04"),
        Err(CheckpointError::BadMagic)
    ));
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        Gdm::from_bytes(&long),
        Err(CheckpointError::Corrupt(_))
    ));
}

/// Rewrites the checksum so that damage reaches the content checks.
fn reseal(bytes: &mut [u8]) {
    let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn damaged_content_with_a_valid_checksum_never_panics() {
    let bytes = model(Metric::Mahalanobis).to_bytes();
    let mut rejected = 0;
    for at in (HEADER_LEN..bytes.len()).step_by(7) {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut bad = bytes.clone();
            bad[at] ^= flip;
            reseal(&mut bad);
            match Gdm::from_bytes(&bad) {
                Ok(gdm) => {
                    // Damage that still makes a valid model (e.g. a changed weight) must give a
                    // sound one.
                    gdm.episodic().network().check_consistency().unwrap();
                    gdm.semantic().network().check_consistency().unwrap();
                }
                Err(CheckpointError::Corrupt(_)) | Err(CheckpointError::Config(_)) => rejected += 1,
                Err(e) => panic!("byte {at}: unexpected error {e:?}"),
            }
        }
    }
    assert!(
        rejected > 0,
        "some damage must be detected by the content checks"
    );
    // A huge declared count must not allocate or panic.
    let mut bad = bytes.clone();
    bad[HEADER_LEN..HEADER_LEN + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    reseal(&mut bad);
    assert!(matches!(
        Gdm::from_bytes(&bad),
        Err(CheckpointError::Corrupt(_))
    ));
}

/// The sequence a model trained last (so that the next sample continues its temporal context)
/// is part of the checkpoint, and an episode end or a replay clears it.
#[test]
fn current_sequence_survives_the_checkpoint() {
    let mut gdm = Gdm::new(GdmConfig::default(), 2).unwrap();
    assert_eq!(gdm.current_sequence(), None);
    let xs = [[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]];
    for id in [7u64, 1 << 63, u64::MAX] {
        let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, id, 1, 2)).collect();
        gdm.train(&samples).unwrap();
        assert_eq!(gdm.current_sequence(), Some(id));
        let back = Gdm::from_bytes(&gdm.to_bytes()).unwrap();
        assert_eq!(back.current_sequence(), Some(id));
    }
    gdm.end_episode();
    assert_eq!(gdm.current_sequence(), None);
    assert_eq!(
        Gdm::from_bytes(&gdm.to_bytes()).unwrap().current_sequence(),
        None
    );
    let samples: Vec<Sample> = xs.iter().map(|x| Sample::labelled(x, 3, 1, 2)).collect();
    gdm.train(&samples).unwrap();
    gdm.replay().unwrap();
    assert_eq!(gdm.current_sequence(), None);
}

#[test]
fn version_1_files_are_still_read_with_nothing_learnt_since_the_last_replay() {
    // Version 2 added, after the replay counter, the samples learnt since the last replay.
    let gdm = model(Metric::Manhattan);
    let v2 = gdm.to_bytes();
    let payload = &v2[HEADER_LEN..];
    let config_len = u64::from_le_bytes(payload[..8].try_into().unwrap()) as usize;
    // config, dim, sequence flag + id, replay counter
    let at = 8 + config_len + 8 + 9 + 8;
    let field = |p: &[u8]| u64::from_le_bytes(p[at..at + 8].try_into().unwrap());
    assert_eq!(
        field(payload),
        15,
        "the 15 samples trained after the last replay"
    );
    let mut p1 = payload[..at].to_vec();
    p1.extend_from_slice(&payload[at + 8..]);
    let mut v1 = b"LGDMCKPT".to_vec();
    v1.extend_from_slice(&1u32.to_le_bytes());
    v1.extend_from_slice(&(p1.len() as u64).to_le_bytes());
    v1.extend_from_slice(&crc32fast::hash(&p1).to_le_bytes());
    v1.extend_from_slice(&p1);
    let back = Gdm::from_bytes(&v1).unwrap();
    let again = back.to_bytes();
    assert_eq!(&again[8..12], &VERSION.to_le_bytes());
    let payload = &again[HEADER_LEN..];
    assert_eq!(field(payload), 0);
    assert_eq!(&payload[..at], &p1[..at]);
    assert_eq!(&payload[at + 8..], &p1[at..]);
}
