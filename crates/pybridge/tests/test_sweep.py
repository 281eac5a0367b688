"""``lgdm.sweep``: a grid of robot runs on Ray — every cell the run it would be alone, failures
reported while the rest finish, finished cells kept on ``--resume``."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from test_sim import without_wall

import lgdm
import lgdm.sim
import lgdm.sweep

pytest.importorskip("ray", reason='sweeps need the ray extra: pip install "lgdm[ray]"')

REPO = Path(__file__).resolve().parents[3]
SMALL = REPO / "examples" / "sweeps" / "small.toml"


def table(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The small example sweep, with one more grid value that fails (an unknown gripper), run
    through the command line."""
    spec = tmp_path_factory.mktemp("spec") / "spec.toml"
    spec.write_text(
        SMALL.read_text().replace(
            'grasp = ["analytic", "random"]',
            'grasp = ["analytic", "random"]\ngripper = ["2f-140", "2f-300"]',
        )
    )
    out = tmp_path_factory.mktemp("sweep")
    done = subprocess.run(
        [sys.executable, "-m", "lgdm.sweep", str(spec), "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 1, done.stderr  # cells failed, and it says so
    assert "2f-300" in done.stderr
    return out


def test_each_cell_is_the_run_done_alone(swept: Path, tmp_path: Path):
    rows = table(swept / "table.csv")
    assert len(rows) == 8  # 2 grasp sources × 2 grippers × 2 seeds
    ok = [r for r in rows if r["status"] == "ok"]
    assert {(r["grasp"], r["seed"]) for r in ok} == {
        (g, s) for g in ("analytic", "random") for s in ("0", "1")
    }
    alone = lgdm.sim.grasp(
        scenario="isolated", rounds=4, grasp="random", gripper="2f-140", seed=1, out=tmp_path / "r"
    )
    cell = swept / "cells" / "grasp=random,gripper=2f-140,seed=1" / "results.json"
    assert without_wall(json.loads(cell.read_text())) == without_wall(alone)
    row = next(r for r in ok if r["cell"] == "grasp=random,gripper=2f-140,seed=1")
    assert float(row["grasp_success_rate"]) == alone["summary"]["grasp_success_rate"]["value"]


def test_a_failing_cell_is_reported_and_the_rest_finish(swept: Path):
    rows = table(swept / "table.csv")
    failed = [r for r in rows if r["status"] != "ok"]
    assert {r["gripper"] for r in failed} == {"2f-300"} and len(failed) == 4
    assert all("ConfigError" in r["status"] and "2f-300" in r["status"] for r in failed)
    summary = table(swept / "summary.csv")
    settings = {s["setting"] for s in summary}
    assert settings == {"grasp=analytic,gripper=2f-140", "grasp=random,gripper=2f-140"}
    assert all(s["seeds"] == "2" for s in summary)
    assert (swept / "summary.png").is_file()


def test_resume_runs_nothing_that_finished(swept: Path):
    before = {p: p.stat().st_mtime_ns for p in swept.glob("cells/*/results.json")}
    assert len(before) == 4
    ran = []
    rows = lgdm.sweep.run(
        json.loads((swept / "spec.json").read_text()),
        out=swept,
        resume=True,
        progress=lambda done, total: ran.append(done),
    )
    after = {p: p.stat().st_mtime_ns for p in swept.glob("cells/*/results.json")}
    assert after == before
    assert len(rows) == 8 and ran  # only the 4 failing cells were tried again


@pytest.mark.parametrize(
    "spec, field",
    [
        ({"sweep": {"command": "sim juggle", "seeds": [0]}}, "sweep.command"),
        ({"sweep": {"command": "sim grasp", "seeds": []}}, "sweep.seeds"),
        ({"sweep": {"command": "sim grasp", "seeds": [0]}, "grid": {"speed": [1]}}, "speed"),
        ({"sweep": {"command": "sim grasp", "seeds": [0]}, "base": {"seed": 3}}, "seed"),
    ],
)
def test_bad_specs_are_config_errors_naming_the_field(spec: dict, field: str, tmp_path: Path):
    with pytest.raises(lgdm.ConfigError, match=field):
        lgdm.sweep.run(spec, out=tmp_path)
    assert not (tmp_path / "cells").exists()


@pytest.mark.parametrize(
    "spec, words",
    [
        ({"base": {"rounds": -1}}, ["base.rounds", "-1", "integer from 0"]),
        ({"base": {"rounds": "three"}}, ["base.rounds", '"three"', "integer from 0"]),
        ({"base": {"rounds": 2**40}}, ["base.rounds", "integer from 0"]),
        ({"base": {"record": 1}}, ["base.record", "true or false"]),
        ({"grid": {"rounds": [2, -1]}}, ["grid.rounds = -1", "rounds=-1,seed=0", "integer"]),
        ({"grid": {"scenario": ["isolated", 3]}}, ["grid.scenario = 3", "a string (one of"]),
        ({"grid": {"gripper": [True]}}, ["grid.gripper = True", "a string (one of"]),
    ],
)
def test_values_of_the_wrong_type_name_the_key_the_cells_and_what_was_expected(
    spec: dict, words: list[str], tmp_path: Path
):
    full = {"sweep": {"command": "sim grasp", "seeds": [0]}, **spec}
    with pytest.raises(lgdm.ConfigError) as e:
        lgdm.sweep.run(full, out=tmp_path)
    for word in words:
        assert word in str(e.value), str(e.value)
    assert "lgdm.sim.grasp" in str(e.value)
    assert not (tmp_path / "cells").exists()


def _descendants(pid: int) -> list[int]:
    """Every living process below ``pid`` (Linux ``/proc``): Ray's raylet and workers may leave
    the sweep's process group, so a kill of the group alone can leave a cell running."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            # The command name, in parentheses, may hold spaces: the fields follow the last ')'.
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, killed and not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def _interrupted_sweep(spec: Path, out: Path, mark: str, finished: str) -> list[str]:
    """Runs the sweep in its own process group and SIGKILLs it with every process below it
    (Ray's) as soon as a cell holds ``mark`` but not ``finished``; returns those cells' names."""
    import os
    import signal
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "lgdm.sweep", str(spec), "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            half = [c for c in (out / "cells").glob("*") if (c / mark).is_file()
                    and not (c / finished).is_file()]  # fmt: skip
            if half:
                break
            time.sleep(0.02)
    finally:
        below = _descendants(proc.pid)
        os.killpg(proc.pid, signal.SIGKILL)
        for pid in below:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        proc.wait()
    # Nothing the sweep started may still write a cell when the resumed sweep looks at it.
    while any(_alive(pid) for pid in below) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [c.name for c in (out / "cells").glob("*")
            if (c / mark).is_file() and not (c / finished).is_file()]  # fmt: skip


def _cells(out: Path, name: str) -> dict[str, bytes]:
    return {c.name: (c / name).read_bytes() for c in sorted((out / "cells").glob("*"))}


def _killed_and_resumed_equals(straight: Path, spec: Path, out: Path, mark: str, finished: str,
                               same: Any) -> None:
    """Kills the sweep of ``spec`` into ``out`` while a cell runs, resumes it, and compares every
    cell's ``finished`` file (through ``same``) and the table with the straight sweep's."""
    half = _interrupted_sweep(spec, out, mark, finished)
    assert half, "the sweep was not caught while a cell ran"
    done = subprocess.run(
        [sys.executable, "-m", "lgdm.sweep", str(spec), "--out", str(out), "--resume"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    for name, text in _cells(out, finished).items():
        assert same(json.loads(text)) == same(json.loads(_cells(straight, finished)[name])), name
    assert (out / "table.csv").read_text() == (straight / "table.csv").read_text()


def test_a_sweep_killed_while_a_sim_cell_runs_resumes_to_the_straight_sweep(tmp_path: Path):
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[sweep]\ncommand = "sim grasp"\nseeds = [0, 1]\n\n'
        '[base]\nscenario = "isolated"\nrounds = 6\n\n[grid]\ngrasp = ["analytic"]\n'
    )
    straight = tmp_path / "straight"
    lgdm.sweep.run(spec, out=straight)
    _killed_and_resumed_equals(straight, spec, tmp_path / "killed", "job.json", "results.json",
                               without_wall)  # fmt: skip


def test_a_sweep_killed_while_a_train_cell_runs_resumes_to_the_straight_sweep(
    small_dataset, tmp_path: Path
):
    from test_cli import without_times

    spec = tmp_path / "train.toml"
    spec.write_text(
        '[sweep]\ncommand = "train"\nseeds = [0, 1]\n\n'
        f'[base]\ndataset = "{small_dataset.path}"\nscenario = "ni"\ntrials = 3\n'
    )
    straight = tmp_path / "straight"
    done = subprocess.run(
        [sys.executable, "-m", "lgdm.sweep", str(spec), "--out", str(straight)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    _killed_and_resumed_equals(straight, spec, tmp_path / "killed", "config.toml",
                               "metrics.json", without_times)  # fmt: skip


def test_resume_starts_afresh_a_cell_that_left_nothing_worth_resuming(tmp_path: Path):
    spec = {"sweep": {"command": "sim grasp", "seeds": [0]}, "base": {"rounds": 1}}
    cell = tmp_path / "cells" / "seed=0"
    cell.mkdir(parents=True)
    (cell / "summary.txt").write_text("half\n")  # a run's file, no job record
    rows = lgdm.sweep.run(spec, out=tmp_path, resume=True)
    assert rows[0]["status"] == "ok"
    # A user's file in a cell is never cleared: the cell fails, naming it.
    other = tmp_path / "other"
    (other / "cells" / "seed=0").mkdir(parents=True)
    (other / "cells" / "seed=0" / "holiday.png").write_text("x")
    rows = lgdm.sweep.run(spec, out=other, resume=True)
    assert "holiday.png" in rows[0]["status"]
    assert (other / "cells" / "seed=0" / "holiday.png").read_text() == "x"


def test_a_train_sweep_runs_scenarios_whose_cells_merge(small_dataset, tmp_path: Path):
    """``command = "train"``: each cell is the run directory ``run_scenario(out=…)`` writes
    alone (metrics.json but wall times), the table reports the test accuracies, and the cells of
    one setting merge (``lgdm.merge_runs``) into the run of all its seeds as trials."""
    from test_cli import without_times

    spec = tmp_path / "train.toml"
    spec.write_text(
        '[sweep]\ncommand = "train"\nseeds = [0, 1]\n\n'
        f'[base]\ndataset = "{small_dataset.path}"\nscenario = "ni"\ntrials = 1\n\n'
        "[grid]\nreplay = [true, false]\n"
    )
    out = tmp_path / "sweep"
    # Its own process, as the command line runs it: Ray keeps state in the process that ran it.
    done = subprocess.run(
        [sys.executable, "-m", "lgdm.sweep", str(spec), "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    rows = table(out / "table.csv")
    assert [r["status"] for r in rows] == ["ok"] * 4
    table_ = lgdm.good_features(small_dataset)
    for row in rows:
        replay = row["replay"] == "true"
        cell = json.loads((out / "cells" / row["cell"] / "metrics.json").read_text())
        alone = lgdm.run_scenario(table_, "ni", trials=1, seed=int(row["seed"]), replay=replay)
        assert without_times(cell) == without_times(alone)
        assert float(row["test_category_accuracy_sm"]) == alone["summary"][
            "test_category_accuracy_sm"
        ]["mean"]
    merged = lgdm.merge_runs(
        [out / "cells" / "replay=true,seed=0", out / "cells" / "replay=true,seed=1"],
        tmp_path / "merged",
    )
    both = lgdm.run_scenario(table_, "ni", trials=2, seed=0, replay=True)
    assert without_times(merged) == without_times(both)
    summary = table(out / "summary.csv")
    assert {r["rate"] for r in summary} >= {"test_category_accuracy_sm"}
    assert (out / "summary.png").stat().st_size > 0


@pytest.fixture
def two_node_cluster(monkeypatch: pytest.MonkeyPatch):
    """A Ray cluster of two nodes on this machine (one CPU each), as docs/guide/sweeps.md says."""
    import shutil
    import socket

    ray_cli = shutil.which("ray") or str(Path(sys.executable).with_name("ray"))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"127.0.0.1:{port}"
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    env = {**__import__("os").environ, "RAY_AUTH_MODE": "disabled"}
    common = ["--num-cpus=1", "--disable-usage-stats"]
    try:
        for args in (
            ["--head", f"--port={port}", "--include-dashboard=false"],
            [f"--address={address}"],
        ):
            subprocess.run([ray_cli, "start", *args, *common], env=env, check=True,
                           capture_output=True)  # fmt: skip
        yield address
    finally:
        subprocess.run([ray_cli, "stop"], env=env, capture_output=True, check=False)


def test_a_two_node_cluster_gives_the_local_table(two_node_cluster: str, tmp_path: Path):
    local = tmp_path / "local"
    cluster = tmp_path / "cluster"
    lgdm.sweep.run(SMALL, out=local)
    lgdm.sweep.run(SMALL, out=cluster, address=two_node_cluster)
    assert (cluster / "table.csv").read_text() == (local / "table.csv").read_text()
    nodes = json.loads((cluster / "nodes.json").read_text())
    assert len(nodes) == 4 and len(set(nodes.values())) == 2, nodes

