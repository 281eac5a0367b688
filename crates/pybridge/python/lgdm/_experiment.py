"""``lgdm.run_scenario``: the paper's lifelong-learning scenarios on a feature table.

The trials run in Rust (``lgdm_gdm::experiment``), the same code as ``lgdm train``: the same
table, settings and seed give exactly the records ``lgdm train`` writes to ``metrics.json``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from os import PathLike
from typing import Any

import numpy as np

from . import _lgdm
from ._errors import InputError
from ._gdm import GDM, _config_json, _features, _ids

__all__ = [
    "LEARNERS",
    "SCENARIOS",
    "merge_runs",
    "resume_scenario",
    "run_scenario",
    "scenario_defaults",
]

#: The scenario names, in the paper's order.
SCENARIOS: tuple[str, ...] = tuple(_lgdm.SCENARIOS)
#: The learner names: the GDM and the baselines (streaming LDA, nearest class mean).
LEARNERS: tuple[str, ...] = tuple(_lgdm.LEARNERS)

_COLUMNS = ("collection", "category", "instance", "sequence", "frame")


def scenario_defaults(scenario: str) -> dict[str, Any]:
    """What a scenario uses when not told otherwise (the same as ``lgdm train``): ``preset``,
    ``replay``, ``epochs``, ``trials``, ``eval_samples`` and ``jobs`` (the number of cores).

    >>> scenario_defaults("batch")["epochs"]
    35
    """
    return dict(_lgdm.scenario_defaults(scenario))


def _collections(value: Any, name: str) -> list[int]:
    if value is None:
        raise InputError(
            f"{name} is needed: pass {name}=[...] or a table from lgdm.good_features, which "
            "carries the dataset's split"
        )
    out = [int(c) for c in np.asarray(value, dtype=np.int64).ravel()]
    if any(c < 0 for c in out):
        raise InputError(f"{name} must hold collection indices ≥ 0, got {out}")
    return out


def run_scenario(
    table: Mapping[str, Any],
    scenario: str,
    *,
    learner: str = "gdm",
    trials: int | None = None,
    seed: int = 0,
    replay: bool | None = None,
    context: bool = True,
    epochs: int | None = None,
    eval_every: int | None = None,
    eval_samples: int | None = None,
    train_samples: int = 0,
    validate: bool = False,
    jobs: int | None = None,
    preset: str | None = None,
    train_collections: Any = None,
    test_collections: Any = None,
    categories: list[str] | None = None,
    return_models: bool = False,
    out: str | PathLike[str] | None = None,
    force: bool = False,
    **overrides: Any,
) -> dict[str, Any] | tuple[dict[str, Any], list[GDM]]:
    """Runs a scenario (``"batch"``, ``"incremental"``, ``"ni"``, ``"nc"`` or ``"nic"``) over
    trials and returns the records ``lgdm train`` writes to ``metrics.json``: per trial the
    held-out instances, per-step figures (``steps``), the final ``test``, ``test_no_context``,
    ``new_instance`` and per-category accuracies, ``forgetting`` (the accuracy matrix over
    tasks — ``categories`` for the semantic memory, ``instances`` for the episodic one — with
    ``average_accuracy``, ``backward_transfer`` and ``average_forgetting``;
    ``np.array(m["accuracy"], dtype=float)`` reads a matrix, NaN above the diagonal), and a
    ``summary`` of means and standard deviations over trials. Accuracies are fractions;
    ``None`` where nothing was scored (as ``null`` in ``metrics.json``).

    ``table`` is the dict :func:`lgdm.good_features` returns (it carries the dataset's split,
    category names and path) or any mapping with ``features`` (n, d) and integer ``collection``,
    ``category``, ``instance``, ``sequence`` and ``frame`` columns, with ``train_collections``,
    ``test_collections`` and ``categories`` given here. Settings default to the scenario's, as
    in ``lgdm train`` (:func:`scenario_defaults`); hyperparameters are a ``preset`` (default:
    the scenario's) plus ``GDM``-style overrides (``episodic__activation_threshold=0.6``).
    ``context=False`` is ``--no-context``; ``jobs`` trials run in parallel threads (the results
    do not depend on it). With ``return_models=True`` the final model of every trial comes
    back too, as :class:`GDM` objects: ``(metrics, models)``.

    ``learner`` is ``"gdm"`` (default) or a baseline on the same features, plans, trials and
    seeds (:data:`LEARNERS`): ``"slda"`` (streaming linear discriminant analysis) or ``"ncm"``
    (nearest class mean), each with a per-instance head (the ``instance_accuracy`` and
    ``category_accuracy_em`` figures) and a per-category head (``category_accuracy_sm``), as
    ``lgdm train --learner``. A baseline has no replay (``replay=True`` is refused), no temporal
    context and no hyperparameters (``preset`` and overrides are refused), and its models are
    not :class:`GDM` objects (``return_models=True`` is refused; with ``out=`` they are saved in
    the run directory).

    With ``out=`` the run writes a run directory as ``lgdm train --out`` does — ``config.toml``
    first, each trial's model and record as it finishes, then ``metrics.json`` and
    ``summary.txt`` and the plots — so an interrupted run is finished
    by :func:`resume_scenario`, runs of other seeds merge with :func:`merge_runs` (or
    ``lgdm merge``), and ``lgdm eval`` reads its models. ``force=True`` replaces a run already
    there, as ``--force``.

    >>> table = lgdm.good_features(lgdm.generate_dataset("data/"))  # doctest: +SKIP
    >>> with_replay = lgdm.run_scenario(table, "nc", trials=2)  # doctest: +SKIP
    >>> without = lgdm.run_scenario(table, "nc", trials=2, replay=False)  # doctest: +SKIP
    """
    if scenario not in SCENARIOS:
        raise InputError(f"unknown scenario {scenario!r}: one of {', '.join(SCENARIOS)}")
    config = None
    hyperparameters_from = f"preset {preset or scenario_defaults(scenario)['preset']}"
    if learner != "gdm":
        hyperparameters_from = f"none (the {learner} learner has no hyperparameters)"
    if preset is not None or overrides:
        if preset is None:
            preset = scenario_defaults(scenario)["preset"]
        config = _config_json(preset, overrides)
        if overrides:
            changed = ", ".join(f"{k}={v!r}" for k, v in sorted(overrides.items()))
            hyperparameters_from += f" with {changed}"
    return _run(
        table,
        scenario,
        train_collections=train_collections,
        test_collections=test_collections,
        categories=categories,
        return_models=return_models,
        config=config,
        trials=trials,
        seed=seed,
        replay=replay,
        context=context,
        epochs=epochs,
        eval_every=eval_every,
        eval_samples=eval_samples,
        train_samples=train_samples,
        validate=validate,
        jobs=jobs,
        hyperparameters_from=hyperparameters_from,
        out=None if out is None else str(out),
        force=force,
        learner=learner,
    )


def resume_scenario(
    table: Mapping[str, Any],
    run_dir: str | PathLike[str],
    *,
    jobs: int | None = None,
    return_models: bool = False,
) -> dict[str, Any] | tuple[dict[str, Any], list[GDM]]:
    """Finishes the run directory ``run_dir`` that :func:`run_scenario` (``out=``) or ``lgdm
    train`` started and did not finish, with its own settings (its ``config.toml``) on the same
    ``table``: the trials it recorded stay as they are, the others are played, and the result —
    ``metrics.json`` and every model — is what a run never stopped gives (as ``lgdm train
    --resume``). A table from another dataset or encoder is refused before anything is written.
    Returns what :func:`run_scenario` returns.
    """
    return _run(
        table,
        "",
        train_collections=None,
        test_collections=None,
        categories=None,
        return_models=return_models,
        jobs=jobs,
        out=str(run_dir),
        resume=True,
    )


def merge_runs(
    runs: Sequence[str | PathLike[str]], out: str | PathLike[str], *, force: bool = False
) -> dict[str, Any]:
    """``lgdm merge``: the run directories ``runs`` (of one experiment, other seeds) merged into
    the new run directory ``out`` — ``metrics.json``, ``config.toml``, ``summary.txt`` and the
    trials' models — as one run with all their trials (5 runs of ``trials=1, seed=k`` merge into
    the ``trials=5`` run). Runs of different experiments, or one seed twice, are refused before
    anything is written. Returns the merged ``metrics.json``.
    """
    return json.loads(_lgdm.merge_runs([str(r) for r in runs], str(out), force=force))


def _run(
    table: Mapping[str, Any],
    scenario: str,
    *,
    train_collections: Any,
    test_collections: Any,
    categories: list[str] | None,
    return_models: bool,
    **settings: Any,
) -> dict[str, Any] | tuple[dict[str, Any], list[GDM]]:
    if not isinstance(table, Mapping):
        raise InputError(f"table must be a mapping of arrays (lgdm.good_features), got {table!r}")
    missing = [k for k in ("features", *_COLUMNS) if k not in table]
    if missing:
        raise InputError(f"table lacks {', '.join(missing)}")
    x = _features(table["features"])
    n = x.shape[0]
    columns = [_ids(table[k], n, k) for k in _COLUMNS]
    train = _collections(
        train_collections if train_collections is not None else table.get("train_collections"),
        "train_collections",
    )
    test = _collections(
        test_collections if test_collections is not None else table.get("test_collections"),
        "test_collections",
    )
    if categories is None:
        categories = table.get("categories")
    if categories is None:
        ids = np.asarray(table["category"])
        categories = [f"category {c}" for c in range(int(ids.max()) + 1 if ids.size else 0)]
    text, models = _lgdm.run_scenario(
        x,
        *columns,
        train,
        test,
        [str(c) for c in categories],
        scenario,
        instances=[str(i) for i in table.get("instances", [])],
        encoder=str(table.get("encoder", "good")),
        dataset=str(table.get("dataset", "")),
        return_models=return_models,
        **settings,
    )
    metrics = json.loads(text)
    if return_models:
        return metrics, [GDM._from_model(m) for m in models]
    return metrics

