"""``lgdm.sweep``: grids of runs (seeds × settings) — robot runs and ``lgdm train`` scenarios —
as Ray tasks, gathered into one table.

A spec (TOML) names the command, the seeds, what every cell shares and the grid::

    [sweep]
    command = "sim grasp"          # "sim grasp", "sim pick-place", "sim packing" or "train"
    seeds = [0, 1, 2]

    [base]                         # keyword arguments of lgdm.sim.<command>, for every cell
    scenario = "isolated"
    rounds = 10

    [grid]                         # every combination of these, for every seed
    grasp = ["analytic", "random"]

``command = "train"`` runs :func:`lgdm.run_scenario`: ``[base]`` then holds ``dataset`` (a
dataset directory, ``lgdm gen-dataset``'s; its GOOD features are computed once per cell) and
``scenario``, and the keywords are ``run_scenario``'s (``trials``, ``replay``, ``epochs``,
hyperparameter overrides such as ``episodic__activation_threshold``, …); a cell's directory is
the run directory ``lgdm train`` writes, and the table reports the test accuracies (means over
the cell's trials).

Each cell — one setting of the grid and one seed — is one Ray task that runs the command as
``lgdm.sim`` (or ``lgdm.run_scenario``) does and writes its own run directory,
``OUT/cells/<cell>/``: the same bytes as the same run done alone. The sweep gathers
``OUT/table.csv`` (one row per cell: the setting, the seed, ``ok`` or the cell's error, and the
summary's rates; ``OUT/nodes.json`` says where each cell ran) and ``OUT/summary.csv`` with
``OUT/summary.png`` (per setting and rate: the mean over the seeds and its 95 % t interval). A
failing cell is reported with its error while the others finish; ``resume=True`` keeps every
cell whose run directory holds its results, finishes a cell that was interrupted while it ran
(``lgdm.sim.resume`` or ``lgdm.resume_scenario`` on its directory: the straight run's
results), starts afresh a cell that left nothing worth resuming, and runs the rest.

Without ``address`` Ray starts on this machine (nothing to set up); with an address
(``ray start --head`` prints it) the cells go to that cluster. Ray is an optional extra:
``pip install "lgdm[ray]"``.

Command line: ``python -m lgdm.sweep SPEC.toml --out DIR [--address ADDR] [--resume]``.
"""

from __future__ import annotations

import argparse
import collections.abc
import csv
import inspect
import itertools
import json
import math
import sys
import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

from ._errors import ConfigError

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = ["Cell", "cells", "main", "read_spec", "run"]

#: The commands a sweep can run, and the ``lgdm.sim`` function each is (``train``:
#: :func:`lgdm.run_scenario`).
COMMANDS = {
    "sim grasp": "grasp",
    "sim pick-place": "pick_place",
    "sim packing": "packing",
    "train": "run_scenario",
}

#: What a ``train`` cell reports: the metrics.json summary's test accuracies (means).
TRAIN_RATES = (
    "test_instance_accuracy",
    "test_category_accuracy_sm",
    "test_category_accuracy_em",
    "test_no_context_category_accuracy_sm",
)

#: The summary's rates a table reports, in its columns' order.
RATES = (
    "grasp_success_rate",
    "placement_success_rate",
    "cleared_fraction",
    "contact_only_success_rate",
    "recognition_accuracy",
)


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a setting of the grid and a seed."""

    #: The grid's keys and this cell's values, in the spec's order.
    setting: tuple[tuple[str, Any], ...]
    seed: int

    @property
    def name(self) -> str:
        """The run directory's name: ``grasp=analytic,seed=0``."""
        parts = [f"{k}={_slug(v)}" for k, v in self.setting] + [f"seed={self.seed}"]
        return ",".join(parts)

    @property
    def setting_name(self) -> str:
        """The setting without the seed: ``grasp=analytic`` (``-`` for an empty grid)."""
        return ",".join(f"{k}={_slug(v)}" for k, v in self.setting) or "-"


def _slug(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, separators=(",", ":"))
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)


def read_spec(path: str | PathLike[str]) -> dict[str, Any]:
    """A spec from its TOML file, checked (see :func:`check_spec`)."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ConfigError(f"{path}: {e}") from e
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: {e}") from e
    try:
        check_spec(spec)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None
    return spec


def check_spec(spec: Mapping[str, Any]) -> None:
    """Refuses a spec that cannot run, naming the field."""
    unknown = set(spec) - {"sweep", "base", "grid"}
    if unknown:
        raise ConfigError(f"unknown table(s) {sorted(unknown)} (known: sweep, base, grid)")
    sweep = spec.get("sweep")
    if not isinstance(sweep, Mapping):
        raise ConfigError("[sweep] is missing")
    unknown = set(sweep) - {"command", "seeds"}
    if unknown:
        raise ConfigError(f"sweep: unknown field(s) {sorted(unknown)} (known: command, seeds)")
    if sweep.get("command") not in COMMANDS:
        raise ConfigError(f"sweep.command: {sweep.get('command')!r} is not one of {list(COMMANDS)}")
    seeds = sweep.get("seeds")
    if not (
        isinstance(seeds, list)
        and seeds
        and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds)
        and len(set(seeds)) == len(seeds)
    ):
        raise ConfigError("sweep.seeds: a non-empty list of distinct integers ≥ 0")
    base = spec.get("base", {})
    grid = spec.get("grid", {})
    if not isinstance(base, Mapping) or not isinstance(grid, Mapping):
        raise ConfigError("[base] and [grid] are tables")
    for key, values in grid.items():
        if not (isinstance(values, list) and values):
            raise ConfigError(f"grid.{key}: a non-empty list of values")
    reserved = {"seed", "out", "force", "progress"}
    for table, keys in (("base", base), ("grid", grid)):
        clash = reserved & set(keys)
        if clash:
            raise ConfigError(f"{table}: {sorted(clash)} are set by the sweep")
    both = set(base) & set(grid)
    if both:
        raise ConfigError(f"{sorted(both)} in both [base] and [grid]")
    from . import sim
    from ._experiment import run_scenario

    function = None
    if sweep["command"] == "train":
        if "dataset" not in base:
            raise ConfigError("base.dataset: a train sweep needs a dataset directory")
        scenario = base.get("scenario", (grid.get("scenario") or [None])[0])
        if scenario is None:
            raise ConfigError("base.scenario: a train sweep needs a scenario (or grid.scenario)")
        # run_scenario's keywords, and hyperparameter overrides (section__field), which
        # run_scenario checks when the cell runs.
        known = set(inspect.signature(run_scenario).parameters) - {"table", "overrides"}
        known |= {"dataset", "scenario"}
        known |= {k for k in (*base, *grid) if "__" in k}
        where = "lgdm.run_scenario"
    else:
        function = getattr(sim, COMMANDS[sweep["command"]])
        known = set(inspect.signature(function).parameters)
        where = f"lgdm.sim.{function.__name__}"
    for table, keys in (("base", base), ("grid", grid)):
        wrong = set(keys) - known
        if wrong:
            raise ConfigError(f"{table}: {sorted(wrong)} are not options of {where}")
    hints = _parameter_hints(run_scenario if sweep["command"] == "train" else function)
    for key, value in base.items():
        _check_value(f"base.{key}", value, hints.get(key), where)
    for key, values in grid.items():
        for value in values:
            cell = "; ".join(c.name for c in cells(spec) if dict(c.setting)[key] == value)
            at = f"grid.{key} = {_toml(value)} (cells {cell})"
            _check_value(at, value, hints.get(key), where)


def _parameter_hints(function: Any) -> dict[str, Any]:
    """``function``'s parameter annotations, evaluated; one that cannot be is left out (and its
    values are then checked by the call)."""
    hints = {}
    for name, parameter in inspect.signature(function).parameters.items():
        annotation = parameter.annotation
        if isinstance(annotation, str):
            try:
                annotation = eval(annotation, function.__globals__)
            except Exception:
                continue
        hints[name] = annotation
    return hints


def _toml(value: Any) -> str:
    return json.dumps(value) if isinstance(value, str) else repr(value)


#: What a value of a Literal's type is called in an error.
_KIND = {str: "a string", int: "an integer", bool: "true or false", float: "a number"}

#: The largest count or index a cell may pass (the Rust side's 32-bit counts).
_MAX_INT = 2**32 - 1


def _expected(hint: Any) -> str | None:
    """What ``hint`` expects of a value from a TOML spec, in words; ``None`` when a spec
    cannot give such a value anyway (callables) or anything goes."""
    if hint is None or hint is Any:
        return None
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Literal:
        # The type only: a value of the right type that is not one of these fails its cells,
        # with the function's own error, while the others run.
        kinds = " or ".join(dict.fromkeys(_KIND.get(type(a), type(a).__name__) for a in args))
        return f"{kinds} (one of " + ", ".join(_toml(a) for a in args) + ")"
    if origin in (typing.Union, types.UnionType):
        words = [w for a in args if a is not type(None) for w in [_expected(a)] if w]
        if any(a is not type(None) and _expected(a) is None for a in args):
            return None
        return " or ".join(dict.fromkeys(words))
    if hint is bool:
        return "true or false"
    if hint is int:
        return f"an integer from 0 to {_MAX_INT}"
    if hint is float:
        return "a finite number"
    if hint is str or hint is PathLike or origin is PathLike:
        return "a string"
    if origin in (list, collections.abc.Sequence):
        return "a list of strings"
    return None


def _fits(value: Any, hint: Any) -> bool:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Literal:
        return any(type(value) is type(a) for a in args)
    if origin in (typing.Union, types.UnionType):
        return any(
            (value is None) if a is type(None) else _fits(value, a) for a in args
        )
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= _MAX_INT
    if hint is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        return ok and math.isfinite(value)
    if hint is str or hint is PathLike or origin is PathLike:
        return isinstance(value, str)
    if origin in (list, collections.abc.Sequence):
        return isinstance(value, list) and all(isinstance(v, str) for v in value)
    return True


def _check_value(where_in_spec: str, value: Any, hint: Any, function: str) -> None:
    """Refuses a value a cell could not pass to ``function``, naming the key, the cells and
    what was expected (not the raw ``TypeError``/``OverflowError`` of the call)."""
    expected = _expected(hint)
    if expected is not None and not _fits(value, hint):
        raise ConfigError(f"{where_in_spec}: {_toml(value)} is not {expected} ({function})")


def cells(spec: Mapping[str, Any]) -> list[Cell]:
    """Every cell of the spec: each setting of the grid (in the spec's order) for each seed."""
    grid = spec.get("grid", {})
    keys = list(grid)
    out = []
    for values in itertools.product(*(grid[k] for k in keys)):
        for seed in spec["sweep"]["seeds"]:
            out.append(Cell(tuple(zip(keys, values, strict=True)), seed))
    return out


def _run_cell(
    spec: Mapping[str, Any], cell: Cell, out: str, start: str = "fresh"
) -> dict[str, Any]:
    """Runs one cell into ``out``; ``{"summary": …}`` or ``{"error": …}``. ``start`` is how
    (:func:`_how_to_start`): ``"fresh"``, ``"resume"`` (finish the interrupted run there) or
    ``"restart"`` (replace what an interrupted start left, which is only a run's own files)."""
    from . import sim

    kwargs = {**spec.get("base", {}), **dict(cell.setting), "seed": cell.seed, "out": out}
    train = spec["sweep"]["command"] == "train"
    if start == "resume":
        # A run the interrupted sweep left behind (a Ray worker that outlived its driver) may
        # have finished it since the sweep looked: then there is nothing to resume.
        done = _finished(Path(out))
        if done is not None:
            return done
        function = _resume_train_cell if train else _resume_sim_cell
        kwargs = {"out": out, "dataset": kwargs.get("dataset")}
    elif train:
        function = _train_cell
    else:
        function = getattr(sim, COMMANDS[spec["sweep"]["command"]])
    if start == "restart":
        kwargs["force"] = True
    node = None
    try:
        import ray

        if ray.is_initialized():
            node = ray.get_runtime_context().get_node_id()
    except ImportError:
        pass
    try:
        results = function(**kwargs)
    except Exception as e:
        return {"error": f"{type(e).__name__}: {e}", "node": node}
    return {"summary": results["summary"], "node": node}


def _train_cell(*, dataset: str, scenario: str, **kwargs: Any) -> dict[str, Any]:
    """A ``train`` cell: ``run_scenario`` on the dataset's GOOD features into ``out``, its
    summary's test accuracies as rates (the means over the cell's trials)."""
    from ._data import Dataset, good_features
    from ._experiment import run_scenario

    metrics = run_scenario(good_features(Dataset(dataset)), scenario, **kwargs)
    return {"summary": _train_summary(metrics)}


def _resume_sim_cell(*, out: str, dataset: Any = None) -> dict[str, Any]:
    """An interrupted robot cell finished as ``lgdm.sim.resume`` does (its own ``job.json``)."""
    from . import sim

    return sim.resume(out)


def _resume_train_cell(*, out: str, dataset: str) -> dict[str, Any]:
    """An interrupted ``train`` cell finished as ``lgdm.resume_scenario`` does."""
    from ._data import Dataset, good_features
    from ._experiment import resume_scenario

    metrics = resume_scenario(good_features(Dataset(dataset)), out)
    return {"summary": _train_summary(metrics)}


def _how_to_start(out: Path) -> str:
    """How a cell that has not finished starts: ``"fresh"`` in a missing or empty directory;
    ``"resume"`` where an interrupted run left its record (``job.json`` of a robot run,
    ``config.toml`` of a ``train`` run); ``"restart"`` where an interrupted start left less
    than that (only a run's own files are then removed; anything else stops the cell)."""
    if (out / "job.json").is_file() or (out / "config.toml").is_file():
        return "resume"
    try:
        entries = [p for p in out.iterdir() if p.name != ".lgdm.lock"]
    except OSError:
        return "fresh"
    return "restart" if entries else "fresh"


def _train_summary(metrics: Mapping[str, Any]) -> dict[str, Any]:
    s = metrics["summary"]
    return {
        "trials": s["trials"],
        **{r: {"value": (s.get(r) or {}).get("mean")} for r in TRAIN_RATES},
    }


def _finished(out: Path) -> dict[str, Any] | None:
    try:
        return {"summary": json.loads((out / "results.json").read_text())["summary"]}
    except (OSError, ValueError, KeyError):
        pass
    try:
        return {"summary": _train_summary(json.loads((out / "metrics.json").read_text()))}
    except (OSError, ValueError, KeyError):
        return None


def run(
    spec: Mapping[str, Any] | str | PathLike[str],
    *,
    out: str | PathLike[str],
    address: str | None = None,
    resume: bool = False,
    progress: Any = None,
) -> list[dict[str, Any]]:
    """Runs the sweep (a spec dict or its TOML file) into ``out`` on Ray — this machine's
    without ``address`` — and writes ``table.csv``, ``summary.csv`` and ``summary.png``.
    Returns the table's rows. ``progress(done, total)`` is called as cells finish."""
    if not isinstance(spec, Mapping):
        spec = read_spec(spec)
    check_spec(spec)
    if "dataset" in spec.get("base", {}):
        # The cells may run elsewhere: the dataset as an absolute path.
        base = {**spec["base"], "dataset": str(Path(spec["base"]["dataset"]).resolve())}
        spec = {**spec, "base": base}
    try:
        import ray
    except ImportError as e:
        raise ConfigError('sweeps run on Ray, an optional extra: pip install "lgdm[ray]"') from e
    out = Path(out)
    (out / "cells").mkdir(parents=True, exist_ok=True)
    all_cells = cells(spec)
    outcome: dict[Cell, dict[str, Any]] = {}
    pending = []
    start: dict[Cell, str] = {}
    for cell in all_cells:
        cell_dir = out / "cells" / cell.name
        done = _finished(cell_dir) if resume else None
        if done is not None:
            outcome[cell] = done
        else:
            pending.append(cell)
            start[cell] = _how_to_start(cell_dir) if resume else "fresh"
    (out / "spec.json").write_text(json.dumps(spec, indent=2, sort_keys=True) + "\n")
    if pending:
        started = not ray.is_initialized()
        if started:
            # No address: a Ray of our own on this machine ("local"), never a cluster some
            # earlier `ray start` left behind (Ray's default would join it).
            ray.init(address=address or "local", include_dashboard=False, log_to_driver=False)
        try:
            task = ray.remote(num_cpus=1)(_run_cell)
            refs = {
                task.remote(dict(spec), cell, str(out / "cells" / cell.name), start[cell]): cell
                for cell in pending
            }
            waiting = list(refs)
            while waiting:
                ready, waiting = ray.wait(waiting, num_returns=1)
                for ref in ready:
                    try:
                        outcome[refs[ref]] = ray.get(ref)
                    except Exception as e:  # the worker itself died
                        outcome[refs[ref]] = {"error": f"{type(e).__name__}: {e}"}
                if progress is not None:
                    progress(len(outcome), len(all_cells))
        finally:
            if started:
                ray.shutdown()
    rows = [_row(cell, outcome[cell]) for cell in all_cells]
    _write_table(out / "table.csv", rows)
    # Where each cell ran this time (Ray's node ids; not part of the table, which is the same
    # wherever the cells ran).
    nodes = {c.name: outcome[c].get("node") for c in all_cells if c in pending}
    (out / "nodes.json").write_text(json.dumps(nodes, indent=2, sort_keys=True) + "\n")
    summary = _summarise(rows)
    _write_table(out / "summary.csv", summary)
    _plot(out / "summary.png", summary)
    return rows


def _row(cell: Cell, outcome: Mapping[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {"cell": cell.name, "setting": cell.setting_name}
    row.update({k: _slug(v) for k, v in cell.setting})
    row["seed"] = cell.seed
    row["status"] = "ok" if "summary" in outcome else outcome["error"]
    summary = outcome.get("summary") or {}
    if "trials" in summary:
        row["trials"] = summary["trials"]
    else:
        row["attempts"] = summary.get("attempts", "")
    for rate in TRAIN_RATES if "trials" in summary else RATES:
        value = (summary.get(rate) or {}).get("value")
        row[rate] = "" if value is None else repr(float(value))
    return row


def _write_table(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    columns: list[str] = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


# Two-sided 97.5 % quantiles of Student's t for 1–30 degrees of freedom.
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
         2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
         2.060, 2.056, 2.052, 2.048, 2.045, 2.042)  # fmt: skip


def _summarise(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per setting and rate: the seeds that ran, the mean and its 95 % t interval."""
    out = []
    for setting in dict.fromkeys(r["setting"] for r in rows):
        mine = [r for r in rows if r["setting"] == setting and r["status"] == "ok"]
        for rate in (*RATES, *TRAIN_RATES):
            values = [float(r[rate]) for r in mine if r.get(rate, "") != ""]
            if not values:
                continue
            n = len(values)
            mean = sum(values) / n
            if n > 1:
                sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))
                half = _T975[min(n - 1, len(_T975)) - 1] * sd / math.sqrt(n)
            else:
                half = float("nan")
            out.append(
                {
                    "setting": setting,
                    "rate": rate,
                    "seeds": n,
                    "mean": repr(mean),
                    "low": repr(mean - half),
                    "high": repr(mean + half),
                }
            )
    return out


def _plot(path: Path, summary: Sequence[Mapping[str, Any]]) -> None:
    """Mean and interval across seeds per setting, one panel per rate (needs matplotlib,
    part of the ``ray`` extra; without it no picture is drawn)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    rates = list(dict.fromkeys(s["rate"] for s in summary))
    if not rates:
        return
    fig, axes = plt.subplots(1, len(rates), figsize=(4 * len(rates), 3.5), squeeze=False)
    for ax, rate in zip(axes[0], rates, strict=True):
        mine = [s for s in summary if s["rate"] == rate]
        x = range(len(mine))
        means = [float(s["mean"]) for s in mine]
        pairs = list(zip(means, mine, strict=True))
        lows = [m - float(s["low"]) if s["seeds"] > 1 else 0.0 for m, s in pairs]
        highs = [float(s["high"]) - m if s["seeds"] > 1 else 0.0 for m, s in pairs]
        ax.errorbar(x, means, yerr=[lows, highs], fmt="o", capsize=4)
        ax.set_xlim(-0.5, len(mine) - 0.5)
        ax.set_xticks(list(x), [s["setting"] for s in mine], rotation=30, ha="right")
        ax.set_ylim(0, 1.05)
        ax.set_title(rate.replace("_", " "))
    fig.suptitle("mean over seeds, 95 % t interval")
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m lgdm.sweep SPEC.toml --out DIR [--address ADDR] [--resume]``."""
    parser = argparse.ArgumentParser(
        prog="python -m lgdm.sweep", description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument("spec", help="the sweep's TOML spec")
    parser.add_argument("--out", required=True, help="the sweep's directory")
    parser.add_argument("--address", help="a Ray cluster's address (default: this machine)")
    parser.add_argument("--resume", action="store_true", help="keep the cells already finished")
    args = parser.parse_args(argv)
    try:
        rows = run(
            args.spec,
            out=args.out,
            address=args.address,
            resume=args.resume,
            progress=lambda done, total: print(f"{done}/{total} cells", file=sys.stderr),
        )
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    failed = [r for r in rows if r["status"] != "ok"]
    for r in failed:
        print(f"cell {r['cell']} failed: {r['status']}", file=sys.stderr)
    where = Path(args.out) / "table.csv"
    print(f"{len(rows) - len(failed)} of {len(rows)} cells ran; table in {where}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
