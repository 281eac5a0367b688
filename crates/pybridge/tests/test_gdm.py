"""Contract of ``lgdm.GDM``: learning, incremental learning with new labels, persistence,
parameters, and the GIL released while Rust works."""

from __future__ import annotations

import pickle
import sys
import threading

import numpy as np
import pytest

import lgdm
from conftest import make_objects


def fit_batch(data: dict[str, np.ndarray], **overrides) -> lgdm.GDM:
    return lgdm.GDM("paper_batch", seed=0, **overrides).fit(
        data["X"], data["instance"], data["category"], data["sequence"], epochs=3
    )


def test_fit_predict_round_trip_beats_chance(objects, held_out):
    model = fit_batch(objects)
    assert model.n_features_in_ == 16
    assert model.n_nodes_episodic_ >= 8
    assert model.n_nodes_semantic_ >= 4
    instance, category, activation, _ = model.predict(held_out["X"], held_out["sequence"])
    assert instance.dtype == np.int64 and category.dtype == np.int64
    assert activation.dtype == np.float32
    assert instance.shape == category.shape == activation.shape == (len(held_out["X"]),)
    assert np.all((activation > 0) & (activation <= 1))
    # Chance is 1/8 for instances and 1/4 for categories.
    assert np.mean(instance == held_out["instance"]) > 0.8
    assert np.mean(category == held_out["category"]) > 0.9
    assert model.score(held_out["X"], held_out["category"], held_out["sequence"]) > 0.9
    scores = model.evaluate(
        held_out["X"], held_out["instance"], held_out["category"], held_out["sequence"]
    )
    assert scores["n"] == len(held_out["X"])
    assert scores["category_accuracy_sm"] == pytest.approx(
        np.mean(category == held_out["category"])
    )
    assert scores["instance_accuracy"] == pytest.approx(np.mean(instance == held_out["instance"]))


def test_same_seed_same_bytes_and_float64_equals_float32(objects):
    a = fit_batch(objects)
    b = fit_batch(objects)
    assert a.to_bytes() == b.to_bytes()
    as32 = dict(objects, X=objects["X"].astype(np.float32))
    assert fit_batch(as32).to_bytes() == a.to_bytes()
    # Any memory layout: Fortran order and strided views give the same model.
    fortran = dict(objects, X=np.asfortranarray(objects["X"]))
    assert fit_batch(fortran).to_bytes() == a.to_bytes()
    wide = np.repeat(objects["X"], 2, axis=1)
    strided = dict(objects, X=wide[:, ::2])
    assert fit_batch(strided).to_bytes() == a.to_bytes()


def test_incremental_learning_with_new_labels():
    first = make_objects(n_categories=2, seed=1)
    later = make_objects(n_categories=2, seed=2, first_category=2)
    model = lgdm.GDM(seed=3)
    for _ in range(2):
        model.partial_fit(first["X"], first["instance"], first["category"], first["sequence"])
    model.end_episode()
    model.replay()
    category = model.predict(later["X"], later["sequence"]).category
    assert not np.isin(category, [2, 3]).any(), "labels 2 and 3 were never taught"
    for _ in range(2):
        model.partial_fit(later["X"], later["instance"], later["category"], later["sequence"])
    model.end_episode()
    model.replay()
    for data in (first, later):
        instance, category, *_ = model.predict(data["X"], data["sequence"])
        assert np.mean(category == data["category"]) > 0.9
        assert np.mean(instance == data["instance"]) > 0.8


def test_labels_are_optional_and_scalar_labels_broadcast():
    data = make_objects(n_categories=2, instances_per_category=1, seed=4)
    model = lgdm.GDM(seed=0)
    model.partial_fit(data["X"])  # unlabelled: weights learn, histograms do not
    instance, category, *_ = model.predict(data["X"])
    assert np.all(instance == -1) and np.all(category == -1)
    for c in (0, 1):
        rows = data["category"] == c
        model.partial_fit(data["X"][rows], instance=10 + c, category=c)
    unlabelled = data["instance"].copy()
    unlabelled[::2] = -1  # -1: no label for that sample
    model.partial_fit(data["X"], instance=unlabelled, category=data["category"])
    instance, category, *_ = model.predict(data["X"], data["sequence"])
    assert np.mean(category == data["category"]) > 0.9
    assert set(np.unique(instance)) <= {-1, 0, 1, 10, 11}


def test_large_label_ids_round_trip():
    data = make_objects(n_categories=2, instances_per_category=1, seed=5)
    big = np.where(data["category"] == 0, 0, 2**32 - 1)
    model = lgdm.GDM("paper_batch", seed=0).fit(data["X"], big, big, data["sequence"], epochs=2)
    category = model.predict(data["X"], data["sequence"]).category
    assert set(np.unique(category)) <= {0, 2**32 - 1}
    assert np.mean(category == big) > 0.9


def test_save_load_same_predictions_and_bytes(objects, held_out, tmp_path):
    model = fit_batch(objects)
    path = tmp_path / "model.lgdm"
    model.save(path)
    loaded = lgdm.GDM.load(path)
    assert path.read_bytes() == model.to_bytes() == loaded.to_bytes()
    for a, b in zip(model.predict(held_out["X"]), loaded.predict(held_out["X"]), strict=True):
        np.testing.assert_array_equal(a, b)
    assert loaded.get_config() == model.get_config()
    assert loaded.get_params() == {"preset": "paper_batch"}  # seed 0 is the default
    unpickled = pickle.loads(pickle.dumps(model))
    assert unpickled.to_bytes() == model.to_bytes()
    assert lgdm.GDM.from_bytes(model.to_bytes()).to_bytes() == model.to_bytes()


def test_training_continues_identically_after_load(objects, tmp_path):
    """Saving and loading mid-stream changes nothing: the sequence state (also of automatic,
    per-call sequences) is part of the checkpoint."""
    a = lgdm.GDM(seed=1)
    a.partial_fit(objects["X"][:40], 0, 0)  # sequence=None: one new sequence per call
    a.save(tmp_path / "mid.lgdm")
    b = lgdm.GDM.load(tmp_path / "mid.lgdm")
    for model in (a, b):
        model.partial_fit(objects["X"][40:80], 1, 1)
        model.partial_fit(objects["X"][80:100], 1, 1, sequence=7)
        model.partial_fit(objects["X"][100:120], 1, 1, sequence=7)  # continues sequence 7
        model.partial_fit(objects["X"][120:160], 2, 2)
    assert a.to_bytes() == b.to_bytes()


def test_sequence_none_starts_a_new_sequence_each_call(objects):
    """Per-call sequences (None) reset the context at every call; one explicit id continued
    across calls does not, so the two models differ."""
    x = objects["X"][:40]
    per_call, continued, explicit = lgdm.GDM(seed=0), lgdm.GDM(seed=0), lgdm.GDM(seed=0)
    for i in range(0, 40, 10):
        per_call.partial_fit(x[i : i + 10], 0, 0)
        continued.partial_fit(x[i : i + 10], 0, 0, sequence=5)
        explicit.partial_fit(x[i : i + 10], 0, 0, sequence=i)
    assert per_call.to_bytes() != continued.to_bytes()
    one_call = lgdm.GDM(seed=0).partial_fit(x, 0, 0, sequence=5)
    assert one_call.to_bytes() == continued.to_bytes()
    np.testing.assert_array_equal(
        per_call.predict(x, sequence=np.repeat(np.arange(4), 10))[0],
        explicit.predict(x, sequence=np.repeat(np.arange(4), 10))[0],
    )


def test_params_protocol():
    model = lgdm.GDM("paper_batch", seed=2, episodic__activation_threshold=0.6)
    params = model.get_params()
    assert params == {"preset": "paper_batch", "seed": 2, "episodic__activation_threshold": 0.6}
    clone = type(model)(**params)
    assert clone.get_config() == model.get_config()
    assert clone.get_config()["episodic"]["activation_threshold"] == pytest.approx(0.6)
    assert model.set_params(semantic__max_nodes=50, preset="paper_incremental") is model
    cfg = model.get_config()
    assert cfg["semantic"]["max_nodes"] == 50
    assert cfg["semantic"]["activation_threshold"] == pytest.approx(0.7)  # paper_incremental
    assert cfg["metric"] == "manhattan"
    assert lgdm.config("paper_batch", metric={"minkowski": {"p": 3}})["metric"] == {
        "minkowski": {"p": 3.0}
    }
    assert "paper_batch" in lgdm.PRESETS
    assert "episodic__activation_threshold=0.6" in repr(
        lgdm.GDM(episodic__activation_threshold=0.6)
    )


def test_fit_starts_afresh_and_set_params_applies_at_fit(objects):
    model = fit_batch(objects)
    before = model.to_bytes()
    model.set_params(episodic__activation_threshold=0.2)
    assert model.to_bytes() == before, "a fitted model keeps its hyperparameters"
    model.fit(objects["X"], objects["instance"], objects["category"], objects["sequence"])
    assert model.get_config()["episodic"]["activation_threshold"] == pytest.approx(0.2)
    assert model.n_nodes_episodic_ < fit_batch(objects).n_nodes_episodic_


def test_replay_and_end_episode():
    data = make_objects(n_categories=2, seed=6)
    model = lgdm.GDM(seed=0).partial_fit(
        data["X"], data["instance"], data["category"], data["sequence"]
    )
    assert model.end_episode() is model
    stats = model.replay()
    assert stats["chains"] == model.n_nodes_episodic_ or stats["chains"] > 0
    assert stats["samples"] >= stats["chains"]


def test_no_context_prediction_differs_in_general(objects):
    model = fit_batch(objects)
    with_tc = model.predict(objects["X"], objects["sequence"])
    without = model.predict(objects["X"], objects["sequence"], no_context=True)
    assert with_tc[2].shape == without[2].shape
    assert not np.array_equal(with_tc[2], without[2])


def test_gil_is_released_while_training():
    """Another Python thread runs while Rust trains, shown by the order of events, not by times.

    Forced GIL switches are put off (a 100 s switch interval), so the two threads' Python code
    can only interleave where one of them gives the GIL up. The worker marks "enter" and
    "return" around each ``partial_fit`` (X float32 and C-ordered, no labels: nothing between the
    marks but the Rust call gives the GIL up). The main thread, started and waiting for the GIL,
    marks "main" as soon as it gets it. If training released the GIL the main thread's mark
    falls between an "enter" and its "return"; if it held the GIL the main thread could run only
    after the worker's last call (its calls stop at the first one the main thread ran inside)."""
    rng = np.random.default_rng(0)
    x = rng.normal(0, 1, (500, 64)).astype(np.float32)
    model = lgdm.GDM(seed=0).partial_fit(x[:50])
    calls = 20
    events: list[str] = []
    main_ran = threading.Event()

    def train() -> None:
        for _ in range(calls):
            events.append("enter")
            model.partial_fit(x)
            events.append("return")
            if main_ran.is_set():
                return

    worker = threading.Thread(target=train)
    interval = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    try:
        worker.start()  # waits (GIL released) until the worker runs; resumes when it gets the GIL
        events.append("main")
        main_ran.set()
        worker.join()
    finally:
        sys.setswitchinterval(interval)
    at = events.index("main")
    assert 0 < at < len(events) - 1, f"the main thread never ran during a training call: {events}"
    assert events[at - 1] == "enter" and events[at + 1] == "return", events
    assert model.n_nodes_episodic_ > 0
