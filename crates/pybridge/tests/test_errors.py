"""Bad input raises an ``lgdm.LgdmError`` subclass with a message saying what and where; it
never crashes the interpreter and never changes the model."""

from __future__ import annotations

import numpy as np
import pytest

import lgdm
from conftest import make_objects


@pytest.fixture
def fitted() -> lgdm.GDM:
    data = make_objects(n_categories=2, instances_per_category=1)
    return lgdm.GDM(seed=0).fit(data["X"], data["instance"], data["category"], data["sequence"])


def test_hierarchy():
    for cls in (
        lgdm.ConfigError,
        lgdm.InputError,
        lgdm.NotFittedError,
        lgdm.CheckpointError,
        lgdm.DatasetError,
    ):
        assert issubclass(cls, lgdm.LgdmError)
    for cls in (lgdm.ConfigError, lgdm.InputError, lgdm.NotFittedError):
        assert issubclass(cls, ValueError)
    assert issubclass(lgdm.NotFittedError, AttributeError)


@pytest.mark.parametrize(
    ("overrides", "field", "message"),
    [
        ({"episodic__activation_threshold": 1.5}, "episodic.activation_threshold", "not in [0, 1]"),
        ({"semantic__kappa": 0.9}, "semantic.kappa", "must be > 1"),
        ({"metric": {"minkowski": {"p": 0.5}}}, "metric.p", "≥ 1"),
        ({"episodic__alphas": [1.0]}, "episodic.alphas", "needs 3"),
        ({"replay__chain_length": 0}, "replay.chain_length", "at least 1"),
        ({"replay__budget": 0}, "replay.budget", "> 0 and at most 1000"),
        ({"replay__budget": 1e9}, "replay.budget", "at most 1000"),
        ({"replay__budget": "some"}, "replay.budget", 'expected "all" or a number'),
        ({"episodic__beta": float("nan")}, "episodic.beta", "finite"),
        ({"episodic__bogus": 1}, "episodic.bogus", "unknown field `bogus`"),
        ({"metric": "taxicab"}, "metric", "unknown variant `taxicab`"),
        ({"seed": -1}, "seed", "seed"),
        ({"episodic__max_age": "ten"}, "episodic.max_age", "invalid type"),
    ],
)
def test_config_errors_name_the_field(overrides, field, message):
    with pytest.raises(lgdm.ConfigError) as info:
        lgdm.GDM(**overrides)
    assert info.value.field == field
    assert message in str(info.value)


def test_unknown_parameters_and_presets():
    with pytest.raises(lgdm.ConfigError, match="unknown parameter `learning_rate`"):
        lgdm.GDM(learning_rate=0.1)
    with pytest.raises(lgdm.ConfigError, match="unknown parameter `memory__beta`"):
        lgdm.GDM(memory__beta=0.1)
    with pytest.raises(lgdm.ConfigError, match="unknown preset `fast`"):
        lgdm.GDM("fast")
    with pytest.raises(lgdm.ConfigError, match="preset must be a string"):
        lgdm.GDM(3)
    model = lgdm.GDM()
    with pytest.raises(lgdm.ConfigError):
        model.set_params(episodic__tau_b=2.0)
    assert model.get_params() == {"preset": "paper_incremental"}, (
        "a failed set_params changes nothing"
    )


@pytest.mark.parametrize(
    ("x", "message"),
    [
        (np.array([["a", "b"], ["c", "d"]]), "real numbers"),
        (np.ones((3, 2), dtype=complex), "real numbers"),
        (np.ones((3, 2), dtype=bool), "real numbers"),
        (np.array([[1.0, None]], dtype=object), "real numbers"),
        ([[1.0, 2.0], [3.0]], "could not be read"),
        (np.ones(16), r"2-D .*reshape\(1, -1\)"),
        (np.ones((2, 2, 16)), "2-D"),
        (np.ones((0, 16)), "no samples"),
        (np.ones((3, 5)), "5 features per sample, but the model was fitted with 16"),
        (np.ones((3, 16)) * np.array([np.nan] + [0.0] * 15), "sample 0: feature 0 is not finite"),
        (np.full((3, 16), np.inf), "not finite"),
        (np.full((3, 16), 1e300), "not finite"),  # overflows float32
    ],
)
def test_bad_features_raise_input_error(fitted, x, message):
    before = fitted.to_bytes()
    with pytest.raises(lgdm.InputError, match=message):
        fitted.partial_fit(x, instance=0, category=0)
    with pytest.raises(lgdm.InputError, match=message):
        fitted.predict(x)
    assert fitted.to_bytes() == before


def test_nan_late_in_the_batch_leaves_the_model_unchanged(fitted):
    x = np.zeros((50, 16))
    x[37, 5] = np.nan
    before = fitted.to_bytes()
    with pytest.raises(lgdm.InputError, match="sample 37: feature 5 is not finite"):
        fitted.partial_fit(x)
    assert fitted.to_bytes() == before


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"instance": np.zeros(4, dtype=np.int64)}, "instance has 4 entries but X has 5 samples"),
        ({"category": [0, 1]}, "category has 2 entries but X has 5 samples"),
        ({"sequence": np.zeros(6, dtype=np.int64)}, "sequence has 6 entries"),
        ({"instance": np.array([0, 1, -2, 0, 0])}, r"instance\[2\] = -2 is not a label"),
        ({"category": np.array([0, 0, 0, 0, 2**32])}, r"category\[4\] = 4294967296 is not a label"),
        ({"category": 2**40}, r"category\[0\] = 1099511627776 is not a label"),
        ({"category": 2**70}, "out of the int64 range"),
        (
            {"instance": np.array([0.0, 1.0, 0.0, 0.0, 0.0])},
            "must hold integers, got dtype float64",
        ),
        ({"instance": 1.5}, "must be an integer"),
        ({"instance": True}, "got a bool"),
        ({"instance": np.zeros((5, 1), dtype=int)}, "must be 1-D"),
        ({"category": ["a", "b", "c", "d", "e"]}, "must hold integers"),
        ({"sequence": np.array([0, 0, -1, 1, 1])}, r"sequence\[2\] = -1: sequence ids must be ≥ 0"),
        (
            {"sequence": np.array([0, 0, 2**64 - 1, 1, 1], dtype=np.uint64)},
            "out of the int64 range",
        ),
    ],
)
def test_bad_labels_and_sequences(fitted, kwargs, message):
    before = fitted.to_bytes()
    with pytest.raises(lgdm.InputError, match=message):
        fitted.partial_fit(np.zeros((5, 16)), **kwargs)
    assert fitted.to_bytes() == before


def test_label_dtypes_are_accepted():
    """Labels of any integer dtype are learnt as the same numbers: a model given the same
    samples and labels in each dtype answers with those labels."""
    rng = np.random.default_rng(0)
    x = np.repeat(np.eye(3, 16) * 5.0, 20, axis=0) + rng.normal(0, 0.01, (60, 16))
    answers = []
    for dtype in (np.int8, np.int32, np.uint16, np.uint32, np.uint64, np.int64):
        instance = np.repeat(np.array([3, 5, 7], dtype=dtype), 20)
        category = np.repeat(np.array([1, 2, 2], dtype=dtype), 20)
        model = lgdm.GDM(seed=0).fit(x, instance, category, epochs=3)
        p = model.predict(np.eye(3, 16) * 5.0)
        answers.append((list(p.instance), list(p.category)))
    assert answers[0] == ([3, 5, 7], [1, 2, 2])
    assert all(a == answers[0] for a in answers)


def test_not_fitted():
    model = lgdm.GDM()
    for call in (
        lambda: model.predict(np.zeros((2, 3))),
        lambda: model.replay(),
        lambda: model.end_episode(),
        lambda: model.save("never.lgdm"),
        lambda: model.n_features_in_,
    ):
        with pytest.raises(lgdm.NotFittedError, match="not been fitted"):
            call()
    assert not hasattr(model, "n_nodes_episodic_")  # scikit-learn's fitted-attribute check


def test_bad_epochs(fitted):
    for epochs in (0, -1, 1.5, True):
        with pytest.raises(lgdm.InputError, match="epochs"):
            fitted.fit(np.zeros((3, 16)), epochs=epochs)


def test_checkpoint_errors(fitted, tmp_path):
    data = fitted.to_bytes()
    with pytest.raises(lgdm.CheckpointError, match="bad magic"):
        lgdm.GDM.from_bytes(b"not a model at all")
    with pytest.raises(lgdm.CheckpointError, match="truncated"):
        lgdm.GDM.from_bytes(data[:-10])
    damaged = bytearray(data)
    damaged[-5] ^= 0xFF
    with pytest.raises(lgdm.CheckpointError, match="checksum"):
        lgdm.GDM.from_bytes(bytes(damaged))
    with pytest.raises(lgdm.CheckpointError, match=r"missing\.lgdm"):
        lgdm.GDM.load(tmp_path / "missing.lgdm")
    with pytest.raises(lgdm.CheckpointError, match="I/O"):
        fitted.save(tmp_path / "no" / "such" / "dir" / "m.lgdm")
    assert not list(tmp_path.iterdir())


def test_sizes_that_would_abort_are_config_errors():
    """`GDM(replay__chain_length=2**62).replay()` used to abort with a capacity overflow; sizes
    past their bound are refused when the model is configured, naming the field."""
    for key, value, field in [
        ("replay__chain_length", 2**62, "replay.chain_length"),
        ("replay__chain_length", 1_000_000_000, "replay.chain_length"),
        ("episodic__max_nodes", 2**40, "episodic.max_nodes"),
    ]:
        with pytest.raises(lgdm.ConfigError) as info:
            lgdm.GDM(**{key: value})
        assert info.value.field == field, (key, value)


def _tiny_table() -> dict:
    """3 collections (2 train, 1 test) × 2 categories × 2 instances × 3 frames of 2-d features."""
    rows = [(c, i, f) for c in range(3) for i in range(4) for f in range(3)]
    return {
        "features": np.array([[i // 2 + 0.01 * f, 0.1 * (i % 2)] for _, i, f in rows], np.float32),
        "collection": np.array([c for c, _, _ in rows]),
        "category": np.array([i // 2 for _, i, _ in rows]),
        "instance": np.array([i for _, i, _ in rows]),
        "sequence": np.array([c * 10 + i for c, i, _ in rows]),
        "frame": np.array([f for _, _, f in rows]),
        "train_collections": [0, 1],
        "test_collections": [2],
        "categories": ["mug", "bowl"],
    }


def test_run_scenario_learners(tmp_path):
    table = _tiny_table()
    assert lgdm.LEARNERS == ("gdm", "slda", "ncm")
    metrics = lgdm.run_scenario(table, "ni", learner="ncm", trials=1)
    assert metrics["learner"] == "ncm"
    assert metrics["summary"]["test_category_accuracy_sm"]["mean"] == 1.0
    out = tmp_path / "run"
    with pytest.raises(lgdm.InputError, match='unknown learner "lda": one of gdm, slda, ncm'):
        lgdm.run_scenario(table, "ni", learner="lda", out=out)
    with pytest.raises(lgdm.ConfigError, match="replay applies to the gdm learner only"):
        lgdm.run_scenario(table, "ni", learner="slda", replay=True, out=out)
    with pytest.raises(lgdm.InputError, match="return_models=True"):
        lgdm.run_scenario(table, "ni", learner="slda", return_models=True, out=out)
    with pytest.raises(lgdm.InputError, match='apply to learner="gdm" only'):
        lgdm.run_scenario(table, "ni", learner="slda", preset="paper_batch", out=out)
    assert not out.exists(), "nothing written for a refused run"
