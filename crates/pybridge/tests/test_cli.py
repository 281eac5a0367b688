"""Results through Python equal the command line's for the same data, model and seed.

What must agree, and is checked here, end to end through the real binary:

1. A scenario run through ``lgdm.run_scenario`` on ``lgdm.good_features`` of a dataset gives
   exactly the ``metrics.json`` records (timing fields aside) and the model bytes that
   ``lgdm train`` writes for the same dataset, settings and seed: both call the same library
   code (``lgdm_gdm::experiment``).
2. A model trained by the CLI (``lgdm train --scenario batch``, fixed seed) and loaded in Python
   has the same bytes as the file, and Python's predictions on the test collections (GOOD
   features computed through ``lgdm.good_features``, rows ordered as ``lgdm eval`` orders them:
   by sequence id, frames in order) give exactly the accuracies, node counts, model size and
   category confusion matrix that ``lgdm eval`` reports for that file.
3. A model trained in Python (fixed seed) and saved is read by ``lgdm eval``, which reports
   exactly the scores Python computes for it.
4. The model a robot run learns (``lgdm sim pick-place``) loads in Python with the run's node
   counts.

Same data and seed giving the same bytes within Python is tested in ``test_gdm.py``. The CLI
binary is looked up in ``$LGDM_BIN``, then ``$CARGO_TARGET_DIR/release/lgdm``, then
``target/release/lgdm`` of the repository; without it these tests are skipped, saying so.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import lgdm

REPO = Path(__file__).resolve().parents[3]


def _find_cli() -> Path | None:
    candidates = []
    if os.environ.get("LGDM_BIN"):
        candidates.append(Path(os.environ["LGDM_BIN"]))
    if os.environ.get("CARGO_TARGET_DIR"):
        candidates.append(Path(os.environ["CARGO_TARGET_DIR"]) / "release" / "lgdm")
    candidates.append(REPO / "target" / "release" / "lgdm")
    return next((c for c in candidates if c.is_file() and os.access(c, os.X_OK)), None)


@pytest.fixture(scope="module")
def cli() -> Path:
    found = _find_cli()
    if found is None:
        pytest.skip(
            "the lgdm binary is not built (cargo build --release -p lgdm-cli, or set LGDM_BIN)"
        )
    return found


def run(cli: Path, *args: object, cache: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "LGDM_CACHE_DIR": str(cache)}
    done = subprocess.run(
        [str(cli), *map(str, args)], capture_output=True, text=True, env=env, check=False
    )
    assert done.returncode == 0, f"lgdm {args[0]} failed:\n{done.stderr}"
    return done


def rows_in_eval_order(table: dict[str, np.ndarray], collections: list[int]) -> np.ndarray:
    """Row indices of `collections`, grouped by sequence id (ascending), frames in order."""
    rows = np.flatnonzero(np.isin(table["collection"], collections))
    return rows[np.lexsort((table["frame"][rows], table["sequence"][rows]))]


def cli_eval(
    cli: Path, model: Path, dataset: Path, out: Path, cache: Path, split: str = "test"
) -> dict:
    run(cli, "eval", "--model", model, "--dataset", dataset, "--split", split, "--out", out,
        "--progress", "none", cache=cache)  # fmt: skip
    result = json.loads((out / "eval.json").read_text())
    with open(out / "confusion.csv") as f:
        confusion = np.array([[int(v) for v in row[1:]] for row in list(csv.reader(f))[1:]])
    return {**result, "confusion": confusion}


def python_eval(model: lgdm.GDM, table: dict[str, np.ndarray], rows: np.ndarray, n_cat: int):
    x, seq = table["features"][rows], table["sequence"][rows]
    inst, cat = table["instance"][rows], table["category"][rows]
    scores = model.evaluate(x, inst, cat, seq)
    predicted = model.predict(x, seq).category
    confusion = np.zeros((n_cat, n_cat + 1), dtype=int)
    for truth, p in zip(cat, predicted, strict=True):
        confusion[truth, p if 0 <= p < n_cat else n_cat] += 1
    return scores, confusion


def assert_same(cli_result: dict, scores: dict, confusion: np.ndarray, model: lgdm.GDM) -> None:
    assert cli_result["n"] == scores["n"]
    for key in ("instance_accuracy", "category_accuracy_em", "category_accuracy_sm"):
        assert cli_result[key] == scores[key], key
    assert cli_result["episodic_nodes"] == model.n_nodes_episodic_
    assert cli_result["semantic_nodes"] == model.n_nodes_semantic_
    assert cli_result["model_size_mb"] == model.size_bytes_ / 1e6
    np.testing.assert_array_equal(cli_result["confusion"], confusion)


def test_cli_trained_model_scores_the_same_in_python(cli, small_dataset, tmp_path):
    ds = small_dataset
    cache = tmp_path / "cache"
    out = tmp_path / "run"
    run(cli, "train", "--scenario", "batch", "--dataset", ds.path, "--trials", 1, "--epochs", 2,
        "--seed", 5, "--out", out, "--progress", "none", cache=cache)  # fmt: skip
    path = out / "model-trial0.lgdm"
    model = lgdm.GDM.load(path)
    assert model.to_bytes() == path.read_bytes()
    assert model.get_config()["seed"] == 5

    table = lgdm.good_features(ds)
    rows = rows_in_eval_order(table, ds.split("test"))
    scores, confusion = python_eval(model, table, rows, len(ds.categories))
    assert scores["category_accuracy_sm"] > 1 / len(ds.categories)  # it learnt something
    assert_same(cli_eval(cli, path, ds.path, tmp_path / "eval", cache), scores, confusion, model)


def test_python_trained_model_scores_the_same_in_the_cli(cli, small_dataset, tmp_path):
    ds = small_dataset
    table = lgdm.good_features(ds)
    train = rows_in_eval_order(table, ds.split("train"))
    model = lgdm.GDM("paper_batch", seed=11).fit(
        table["features"][train],
        table["instance"][train],
        table["category"][train],
        table["sequence"][train],
        epochs=2,
    )
    path = tmp_path / "python.lgdm"
    model.save(path)
    rows = rows_in_eval_order(table, ds.split("test"))
    scores, confusion = python_eval(model, table, rows, len(ds.categories))
    result = cli_eval(cli, path, ds.path, tmp_path / "eval", tmp_path / "cache")
    assert_same(result, scores, confusion, model)


TIMING = {"seconds", "train_seconds", "inference_ms_per_sample"}


def without_times(value):
    """metrics.json without the wall-clock fields, which differ from run to run."""
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k not in TIMING}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


@pytest.mark.parametrize(
    ("scenario", "cli_args", "py_args"),
    [
        ("nc", [], {}),
        ("ni", ["--no-replay", "--no-context"], {"replay": False, "context": False}),
    ],
)
def test_run_scenario_equals_the_cli_metrics(
    cli, small_dataset, tmp_path, scenario, cli_args, py_args
):
    ds = small_dataset
    out = tmp_path / "run"
    run(cli, "train", "--scenario", scenario, "--dataset", ds.path, "--trials", 2, "--seed", 4,
        "--out", out, "--progress", "none", *cli_args, cache=tmp_path / "cache")  # fmt: skip
    from_cli = json.loads((out / "metrics.json").read_text())
    table = lgdm.good_features(ds)
    from_python, models = lgdm.run_scenario(
        table, scenario, trials=2, seed=4, return_models=True, **py_args
    )
    assert without_times(from_python) == without_times(from_cli)
    assert from_python["trials"][1]["seed"] == 5
    for t, model in enumerate(models):
        assert model.to_bytes() == (out / f"model-trial{t}.lgdm").read_bytes()



def test_run_directories_from_python_are_the_clis(cli, small_dataset, tmp_path):
    """``run_scenario(out=…)`` writes the run directory ``lgdm train --out`` writes (config.toml,
    metrics.json but wall times, summary.txt's rows, the models, the plots); ``resume_scenario``
    finishes a run cut after its first trial to the same bytes; ``merge_runs`` of two one-trial
    runs is the two-trial run, and ``lgdm merge`` and ``lgdm eval`` read what Python wrote."""
    ds = small_dataset
    cache = tmp_path / "cache"
    cli_out = tmp_path / "cli"
    run(cli, "train", "--scenario", "ni", "--dataset", ds.path, "--trials", 2, "--seed", 4,
        "--out", cli_out, "--progress", "none", cache=cache)  # fmt: skip
    table = lgdm.good_features(ds)
    py_out = tmp_path / "py"
    metrics = lgdm.run_scenario(table, "ni", trials=2, seed=4, out=py_out)
    written = json.loads((py_out / "metrics.json").read_text())
    assert without_times(metrics) == without_times(written)
    assert without_times(metrics) == without_times(
        json.loads((cli_out / "metrics.json").read_text())
    )
    assert (py_out / "config.toml").read_text() == (cli_out / "config.toml").read_text()
    for t in range(2):
        name = f"model-trial{t}.lgdm"
        assert (py_out / name).read_bytes() == (cli_out / name).read_bytes()
    rows = lambda d: (d / "summary.txt").read_text().splitlines()[:5]  # noqa: E731
    assert rows(py_out) == rows(cli_out)
    pictures = sorted(p.name for p in cli_out.glob("*.png"))
    assert len(pictures) == 6
    for name in pictures:
        assert (py_out / name).read_bytes() == (cli_out / name).read_bytes(), name
    # A run directory is not written over without force=True.
    with pytest.raises(lgdm.InputError, match="force"):
        lgdm.run_scenario(table, "ni", trials=2, seed=4, out=py_out)

    # Cut after trial 0 (trial 1's model and record, and metrics.json, never written) and resumed.
    cut = tmp_path / "cut"
    lgdm.run_scenario(table, "ni", trials=2, seed=4, out=cut)
    for name in ("model-trial1.lgdm", "metrics.json", "summary.txt"):
        (cut / name).unlink()
    (cut / "trials" / "trial-1.json").unlink()
    resumed, models = lgdm.resume_scenario(table, cut, return_models=True)
    assert without_times(resumed) == without_times(metrics)
    assert (cut / "model-trial1.lgdm").read_bytes() == (py_out / "model-trial1.lgdm").read_bytes()
    assert models[1].to_bytes() == (py_out / "model-trial1.lgdm").read_bytes()

    # Two one-trial runs (seeds 4 and 5) merge into the two-trial run, in Python and in the CLI.
    one = [tmp_path / "seed4", tmp_path / "seed5"]
    for seed, out in zip((4, 5), one, strict=True):
        lgdm.run_scenario(table, "ni", trials=1, seed=seed, out=out)
    merged = lgdm.merge_runs(one, tmp_path / "merged")
    assert without_times(merged) == without_times(metrics)
    for name in pictures:
        assert (tmp_path / "merged" / name).read_bytes() == (py_out / name).read_bytes(), name
    run(cli, "merge", *one, "--out", tmp_path / "cli-merged", cache=cache)
    assert without_times(json.loads((tmp_path / "cli-merged" / "metrics.json").read_text())) == (
        without_times(metrics)
    )
    with pytest.raises(lgdm.InputError, match="different experiments"):
        other = tmp_path / "nc"
        lgdm.run_scenario(table, "nc", trials=1, seed=6, out=other)
        lgdm.merge_runs([one[0], other], tmp_path / "refused")
    assert not (tmp_path / "refused").exists()


def test_pick_place_model_loads_in_python(cli, tmp_path):
    """The model a robot run learnt (``lgdm sim pick-place``) loads with ``lgdm.GDM.load``, with
    the node counts the run reports and GOOD's 675 inputs."""
    out = tmp_path / "pp"
    run(cli, "sim", "pick-place", "--rounds", "1", "--seed", "2", "--objects", "5",
        "--progress", "none", "--out", out, cache=tmp_path / "cache")
    results = json.loads((out / "results.json").read_text())
    last = results["recognition"]["memory"][-1]
    model = lgdm.GDM.load(out / "model.lgdm")
    assert model.n_features_in_ == 675
    assert model.n_nodes_episodic_ == last["episodic_nodes"] >= 2
    assert model.n_nodes_semantic_ == last["semantic_nodes"]
    assert json.loads((out / "model.json").read_text())["encoder"] == "good"


@pytest.mark.parametrize("learner", ["slda", "ncm"])
def test_baselines_through_python_equal_the_cli_metrics(cli, small_dataset, tmp_path, learner):
    """A baseline (``--learner``) through ``run_scenario`` gives the CLI's metrics.json; its
    model is refused by ``GDM.load``, naming the learner, and scored by ``lgdm eval`` as the
    trial scored it (and ``--no-context``, the GDM's, is refused with nothing written)."""
    ds = small_dataset
    out = tmp_path / "run"
    run(cli, "train", "--scenario", "ni", "--learner", learner, "--dataset", ds.path,
        "--trials", 2, "--seed", 4, "--out", out, "--progress", "none",
        cache=tmp_path / "cache")  # fmt: skip
    from_cli = json.loads((out / "metrics.json").read_text())
    assert from_cli["learner"] == learner
    assert from_cli["replay"] is False and from_cli["context"] is False
    from_python = lgdm.run_scenario(lgdm.good_features(ds), "ni", learner=learner, trials=2, seed=4)
    assert without_times(from_python) == without_times(from_cli)
    assert from_cli["summary"]["test_category_accuracy_sm"]["mean"] > 1 / len(ds.categories)

    model = out / "model-trial0.lgdm"
    with pytest.raises(lgdm.CheckpointError, match=f"a model of the {learner} learner"):
        lgdm.GDM.load(model)
    scored = cli_eval(cli, model, ds.path, tmp_path / "eval", tmp_path / "cache", split="all")
    assert scored["learner"] == learner and scored["context"] is False
    # Every collection: the trained instances' training collections (NI's last step scored all
    # of them), their test collections, and the held-out instances' collections.
    trial = from_cli["trials"][0]
    parts = [trial["steps"][-1]["train"], trial["test"], trial["new_instance"]]
    assert scored["n"] == sum(p["n"] for p in parts)
    for key in ["instance_accuracy", "category_accuracy_em", "category_accuracy_sm"]:
        hits = sum(round(p[key] * p["n"]) for p in parts)
        assert round(scored[key] * scored["n"]) == hits, key
    assert scored["confusion"].sum() == scored["n"]

    env = {**os.environ, "LGDM_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run(
        [str(cli), "eval", "--model", str(model), "--dataset", str(ds.path), "--no-context",
         "--out", str(tmp_path / "eval-nc"), "--progress", "none"],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    assert done.returncode != 0
    assert "--no-context applies to a GDM model only" in done.stderr, done.stderr
    assert learner in done.stderr
    assert not (tmp_path / "eval-nc").exists()


def test_cli_refuses_an_unknown_learner_and_replay_for_a_baseline(cli, tmp_path):
    env = {**os.environ, "LGDM_CACHE_DIR": str(tmp_path / "cache")}
    for args, message in [
        (["--learner", "lda"], "'lda'"),
        (["--learner", "slda", "--replay"], "--replay applies to --learner gdm only"),
        (["--learner", "ncm", "--preset", "paper_batch"], "--preset applies to --learner gdm"),
    ]:
        out = tmp_path / "run"
        done = subprocess.run(
            [str(cli), "train", "--scenario", "ni", *args, "--out", str(out), "--progress",
             "none"],
            capture_output=True, text=True, env=env, check=False,
        )  # fmt: skip
        assert done.returncode != 0, args
        assert message in done.stderr, done.stderr
        assert not out.exists(), args
