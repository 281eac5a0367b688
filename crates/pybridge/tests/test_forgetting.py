"""Forgetting from Python: ``lgdm.run_scenario``'s metrics carry each trial's accuracy matrix
over tasks and ACC, BWT and F (computed in Rust, ``experiment::forgetting``), and the summary
their mean and spread; the matrix reads into numpy, with NaN where a task is not yet learnt."""

from __future__ import annotations

import numpy as np

import lgdm


def _matrix(m: dict) -> np.ndarray:
    return np.array(m["accuracy"], dtype=float)


def test_nc_metrics_expose_the_accuracy_matrix_and_its_numbers(small_dataset, tmp_path):
    table = lgdm.good_features(small_dataset)
    metrics = lgdm.run_scenario(table, "nc", trials=2, seed=3, out=tmp_path / "run")
    for trial in metrics["trials"]:
        f = trial["forgetting"]
        cats = f["categories"]
        # The small dataset's 10 categories arrive as 4, 2, 2, 2: one task per step.
        assert [t["step"] for t in cats["tasks"]] == [1, 2, 3, 4]
        assert [len(t["labels"]) for t in cats["tasks"]] == [4, 2, 2, 2]
        assert cats["measured_after_step"] == [1, 2, 3, 4]
        for m in (cats, f["instances"]):
            r = _matrix(m)
            assert r.shape == (4, 4)
            lower = np.tril(np.ones((4, 4), dtype=bool))
            assert np.isfinite(r[lower]).all() and np.isnan(r[~lower]).all()
            assert ((r[lower] >= 0) & (r[lower] <= 1)).all()
            # The literature's definitions, recomputed from the matrix.
            last = r[-1]
            assert np.isclose(m["average_accuracy"], last.mean())
            assert np.isclose(m["backward_transfer"], np.mean(last[:-1] - np.diag(r)[:-1]))
            best = [r[j:-1, j].max() for j in range(3)]
            assert np.isclose(m["average_forgetting"], np.mean(np.array(best) - last[:-1]))
        # Every test sample is in a task, so the last row weighted by the tasks' test samples
        # is the final test accuracy of the semantic memory.
        n = np.array([t["test_samples"] for t in cats["tasks"]])
        assert n.sum() == trial["test"]["n"]
        weighted = float((n * _matrix(cats)[-1]).sum() / n.sum())
        assert np.isclose(weighted, trial["test"]["category_accuracy_sm"])
    summary = metrics["summary"]["forgetting"]
    values = [t["forgetting"]["categories"]["backward_transfer"] for t in metrics["trials"]]
    assert np.isclose(summary["categories"]["backward_transfer"]["mean"], np.mean(values))
    assert np.isclose(summary["categories"]["backward_transfer"]["std"], np.std(values, ddof=1))
    run = tmp_path / "run"
    assert "average forgetting F" in (run / "summary.txt").read_text()
    for name in ("forgetting_categories.png", "forgetting_instances.png"):
        assert (run / name).read_bytes().startswith(b"\x89PNG")


def test_one_task_has_no_transfer_or_forgetting(small_dataset):
    """ni brings every category and instance in its first step: one task, BWT and F null."""
    table = lgdm.good_features(small_dataset)
    metrics = lgdm.run_scenario(table, "ni", trials=1)
    f = metrics["trials"][0]["forgetting"]["categories"]
    assert len(f["tasks"]) == 1 and _matrix(f).shape == (1, 1)
    assert f["backward_transfer"] is None and f["average_forgetting"] is None
    assert np.isclose(f["average_accuracy"], metrics["trials"][0]["test"]["category_accuracy_sm"])
    assert metrics["summary"]["forgetting"]["categories"]["backward_transfer"]["mean"] is None
