//! Invariant: every size a user can type (chain length, node caps, context depth, input
//! dimension, label levels) or a checkpoint can declare has a documented finite bound, checked
//! where the value enters with a typed error naming it; within the bounds nothing allocates out
//! of proportion (the longest chains replay on a small model at once).

use lgdm_gdm::checkpoint::HEADER_LEN;
use lgdm_gdm::config::{MAX_CHAIN_LENGTH, MAX_CONTEXT_DEPTH, MAX_DIM, MAX_LEVELS, MAX_NODES};
use lgdm_gdm::{
    CheckpointError, ConfigError, GammaGwr, Gdm, GdmConfig, GdmError, MemoryParams, Metric, Sample,
};

fn field_of(result: Result<Gdm, GdmError>) -> String {
    match result {
        Err(GdmError::Config(ConfigError::Invalid { field, .. })) => field,
        other => panic!("expected a config error, got {other:?}"),
    }
}

#[test]
fn sizes_past_their_bound_are_config_errors_naming_the_field() {
    type Edit = fn(&mut GdmConfig);
    let cases: [(&str, Edit); 6] = [
        ("replay.chain_length", |c| {
            c.replay.chain_length = Some(MAX_CHAIN_LENGTH + 1)
        }),
        ("replay.chain_length", |c| {
            c.replay.chain_length = Some(1 << 62)
        }),
        ("episodic.max_nodes", |c| {
            c.episodic.max_nodes = Some(MAX_NODES + 1)
        }),
        ("semantic.max_nodes", |c| {
            c.semantic.max_nodes = Some(usize::MAX)
        }),
        ("episodic.context_depth", |c| {
            c.episodic.context_depth = MAX_CONTEXT_DEPTH + 1
        }),
        ("semantic.context_depth", |c| {
            c.semantic.context_depth = usize::MAX
        }),
    ];
    for (field, edit) in cases {
        let mut config = GdmConfig::default();
        edit(&mut config);
        assert_eq!(field_of(Gdm::new(config, 3)), field);
    }
    // As typed in a config file: `[replay] chain_length = 1000000000`.
    let config: GdmConfig = toml::from_str("[replay]\nchain_length = 1000000000\n").unwrap();
    assert_eq!(field_of(Gdm::new(config, 3)), "replay.chain_length");
    let config: GdmConfig =
        serde_json::from_str(r#"{"episodic": {"max_nodes": 4611686018427387904}}"#).unwrap();
    assert_eq!(field_of(Gdm::new(config, 3)), "episodic.max_nodes");
}

#[test]
fn the_input_dimension_is_bounded() {
    for dim in [MAX_DIM + 1, 1 << 31, usize::MAX] {
        match Gdm::new(GdmConfig::default(), dim) {
            Err(GdmError::DimensionTooLarge { dim: d, max }) => {
                assert_eq!((d, max), (dim, MAX_DIM));
            }
            other => panic!("dim {dim}: {other:?}"),
        }
        let net = GammaGwr::new(MemoryParams::default(), Metric::Manhattan, dim, 1);
        assert!(matches!(net, Err(GdmError::DimensionTooLarge { .. })));
    }
    let gdm = Gdm::new(GdmConfig::default(), MAX_DIM).unwrap();
    assert_eq!(gdm.dim(), MAX_DIM);
}

#[test]
fn label_levels_are_bounded() {
    for levels in [0, MAX_LEVELS + 1, usize::MAX] {
        match GammaGwr::new(MemoryParams::default(), Metric::Manhattan, 2, levels) {
            Err(GdmError::Config(e)) => assert_eq!(e.field(), Some("levels")),
            other => panic!("{levels} levels: {other:?}"),
        }
    }
    let net = GammaGwr::new(MemoryParams::default(), Metric::Manhattan, 2, MAX_LEVELS).unwrap();
    assert_eq!(net.levels(), MAX_LEVELS);
}

/// A small model whose episodic memory holds temporal cycles (every sequence visits three
/// clusters and comes back), so RNATs run to their full length.
fn cyclic_model(config: GdmConfig) -> Gdm {
    let xs: Vec<[f32; 2]> = (0..90)
        .map(|i| {
            let k = (i % 3) as f32;
            [k * 4.0 + 0.01 * (i % 7) as f32, 0.02 * (i % 5) as f32]
        })
        .collect();
    let samples: Vec<Sample> = xs
        .iter()
        .enumerate()
        .map(|(i, x)| Sample::labelled(x, (i / 30) as u64, (i % 3) as u32, (i % 3) as u32))
        .collect();
    let mut gdm = Gdm::new(config, 2).unwrap();
    gdm.train(&samples).unwrap();
    gdm.end_episode();
    gdm
}

#[test]
fn the_longest_chains_replay() {
    let mut config = GdmConfig::default();
    config.replay.chain_length = Some(MAX_CHAIN_LENGTH);
    let mut gdm = cyclic_model(config);
    let nodes = gdm.episodic().len();
    let stats = gdm.replay().unwrap();
    assert_eq!(stats.chains, nodes);
    // Chains through the cycle run to the bound; none is longer.
    assert!(stats.samples <= nodes * MAX_CHAIN_LENGTH);
    assert!(stats.samples > MAX_CHAIN_LENGTH, "{stats:?}");
    gdm.episodic().network().check_consistency().unwrap();
}

/// Replaces the checkpoint's config JSON and recomputes the header.
fn with_config(bytes: &[u8], edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
    let len = u64::from_le_bytes(bytes[HEADER_LEN..HEADER_LEN + 8].try_into().unwrap()) as usize;
    let start = HEADER_LEN + 8;
    let mut doc: serde_json::Value = serde_json::from_slice(&bytes[start..start + len]).unwrap();
    edit(&mut doc);
    let text = serde_json::to_vec(&doc).unwrap();
    let mut payload = (text.len() as u64).to_le_bytes().to_vec();
    payload.extend_from_slice(&text);
    payload.extend_from_slice(&bytes[start + len..]);
    let mut out = bytes[..12].to_vec();
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

#[test]
fn checkpoints_are_held_to_the_same_limits() {
    let mut config = GdmConfig::default();
    config.episodic.max_nodes = Some(50);
    let gdm = cyclic_model(config);
    let bytes = gdm.to_bytes();
    assert_eq!(Gdm::from_bytes(&with_config(&bytes, |_| {})).unwrap(), gdm);
    let over = with_config(&bytes, |c| {
        c["replay"]["chain_length"] = 1_000_000_000.into()
    });
    match Gdm::from_bytes(&over) {
        Err(CheckpointError::Config(e)) => assert_eq!(e.field(), Some("replay.chain_length")),
        other => panic!("{other:?}"),
    }
    // More nodes than the stored cap: the file is inconsistent.
    let nodes = gdm.episodic().len();
    assert!(nodes > 2);
    let capped = with_config(&bytes, |c| c["episodic"]["max_nodes"] = (nodes - 1).into());
    match Gdm::from_bytes(&capped) {
        Err(CheckpointError::Corrupt(msg)) => assert!(msg.contains("caps"), "{msg}"),
        other => panic!("{other:?}"),
    }
}
