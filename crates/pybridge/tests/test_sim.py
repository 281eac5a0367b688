"""``lgdm.sim``: the robot from Python — results as ``results.json`` holds them, the same run as
the command line's, grasp sources written in Python, typed errors."""

from __future__ import annotations

import inspect
import json
import re
import signal
import subprocess
import typing
from pathlib import Path

import numpy as np
import pytest
from test_cli import _find_cli

import lgdm
import lgdm.sim


def without_wall(results: dict) -> dict:
    """The results but for wall-clock times, which no two runs share."""
    r = json.loads(json.dumps(results))
    r.pop("wall", None)
    for key in ("attempts", "rounds"):
        for item in r.get(key, []):
            item.pop("wall", None)
    return r


def test_grasp_returns_the_results_and_writes_the_run_directory(tmp_path: Path):
    seen = []
    r = lgdm.sim.grasp(
        scenario="isolated",
        grasp="analytic",
        rounds=3,
        seed=11,
        out=tmp_path / "run",
        progress=lambda stage, done, total: seen.append((stage, done, total)),
    )
    s = r["summary"]
    assert s["attempts"] == len(r["attempts"]) >= 3
    assert s["grasp_success_rate"]["successes"] > 0
    assert {"value", "wilson_low", "wilson_high"} <= set(s["placement_success_rate"])
    assert seen[-1] == ("rounds", 3, 3)
    written = json.loads((tmp_path / "run" / "results.json").read_text())
    assert without_wall(written) == without_wall(r)
    assert (tmp_path / "run" / "sim.toml").is_file()


def test_a_callable_that_finds_nothing_is_asked_every_attempt():
    crops = []

    def nothing(crop: dict) -> list:
        crops.append(crop)
        return []

    r = lgdm.sim.grasp(grasp=nothing, rounds=3, seed=11)
    s = r["summary"]
    assert s["grasp_success_rate"]["value"] == 0.0
    assert len(crops) >= s["attempts"] >= 3
    assert {a["reason"] for a in r["attempts"]} <= {"no_grasp_found", "wider_than_gripper"}
    crop = crops[0]
    side = crop["rgb"].shape[0]
    assert crop["rgb"].shape == (side, side, 3) and crop["rgb"].dtype == np.uint8
    assert crop["depth"].shape == (side, side) and crop["depth"].dtype == np.float32
    # The table is under the object: the depth at the table is the crop's table depth.
    assert 0.3 < crop["table_depth_m"] < 0.7
    assert np.nanmax(crop["depth"]) == pytest.approx(crop["table_depth_m"], abs=0.05)
    assert crop["focal_px"] > 0 and crop["stroke_m"] == pytest.approx(0.14)


def test_a_callable_gives_the_grasps_the_analytic_source_would():
    """A callable answering with what the analytic source answers (through a first run's
    recorded crop grasps) drives the robot to the same outcomes."""
    reference = lgdm.sim.grasp(rounds=2, seed=5)
    recorded = [a["grasp"]["crop"] for a in reference["attempts"] if a["grasp"]]
    assert recorded
    asked = iter(recorded)

    def replay(crop: dict) -> list:
        g = next(asked, None)
        return [] if g is None else [g]

    r = lgdm.sim.grasp(grasp=replay, rounds=1, seed=5)
    assert r["attempts"][0]["grasp"]["crop"]["center_px"] == recorded[0]["center_px"]
    assert r["attempts"][0]["grasp_success"] == reference["attempts"][0]["grasp_success"]


def test_a_callable_decodes_with_the_runs_decoder_settings(tmp_path: Path):
    """The crop carries the run's ``[attempt.decode]``, and ``decode_grasps`` takes it: a
    network wrapped as a callable decodes as ``--grasp network`` does under any ``sim.toml``."""
    lgdm.sim.grasp(rounds=1, seed=11, out=tmp_path / "first")
    toml = (tmp_path / "first" / "sim.toml").read_text()
    assert "quality_threshold = 0.2\n" in toml and "min_distance_px = 20\n" in toml
    config = tmp_path / "sim.toml"
    config.write_text(toml.replace("quality_threshold = 0.2\n", "quality_threshold = 0.55\n")
                      .replace("min_distance_px = 20\n", "min_distance_px = 7\n"))
    seen = []

    def nothing(crop: dict) -> list:
        seen.append(crop["decode"])
        return []

    lgdm.sim.grasp(grasp=nothing, rounds=1, seed=11, config=config)
    assert seen and seen[0] == pytest.approx({"quality_threshold": 0.55, "min_distance_px": 7,
                                              "quality_sigma_px": 2.0, "width_sigma_px": 1.0})
    assert isinstance(seen[0]["min_distance_px"], int)
    # One peak of quality 0.5: found with train_ae's threshold (0.2), not with the run's 0.55.
    q = np.zeros((56, 56), np.float32)
    q[20:31, 20:31] = 0.5
    c, s, w = np.ones_like(q), np.zeros_like(q), np.full_like(q, 0.3)
    assert len(lgdm.sim.decode_grasps(q, c, s, w)) == 1
    assert lgdm.sim.decode_grasps(q, c, s, w, decode=seen[0]) == []
    assert len(lgdm.sim.decode_grasps(q, c, s, w, decode={"quality_threshold": 0.45})) == 1
    with pytest.raises(lgdm.LgdmError, match="unknown setting `jaw`"):
        lgdm.sim.decode_grasps(q, c, s, w, decode={"jaw": 1.0})
    with pytest.raises(lgdm.LgdmError, match="quality_threshold"):
        lgdm.sim.decode_grasps(q, c, s, w, decode={"quality_threshold": float("nan")})


def test_a_failing_callable_names_itself_and_keeps_its_exception():
    def broken_network(crop: dict) -> list:
        raise ValueError("weights missing")

    with pytest.raises(lgdm.LgdmError, match=r"broken_network.*weights missing") as e:
        lgdm.sim.grasp(grasp=broken_network, rounds=1)
    assert isinstance(e.value.__cause__, ValueError)

    def not_a_list(crop: dict) -> object:
        return 3

    with pytest.raises(lgdm.LgdmError, match="not a list"):
        lgdm.sim.grasp(grasp=not_a_list, rounds=1)

    def no_width(crop: dict) -> list:
        return [{"center_px": (112, 112), "angle": 0.0}]

    with pytest.raises(lgdm.LgdmError, match="width_px"):
        lgdm.sim.grasp(grasp=no_width, rounds=1)


@pytest.mark.parametrize(
    "grasp, field",
    [
        ({"jaw_px": 0}, "jaw_px"),
        ({"jaw_px": -10}, "jaw_px"),
        ({"jaw_px": True}, "jaw_px"),
        ({"width_px": 1e9}, "width_px"),
        ({"width_px": True}, "width_px"),
        ({"angle": 1e30}, "angle"),
        ({"angle": False}, "angle"),
        ({"quality": True}, "quality"),
        ({"center_px": (1e6, 112)}, "center_px"),
        ({"center_px": (112, -5000)}, "center_px"),
        ({"center_px": (True, 112)}, "center_px"),
    ],
)
def test_a_grasp_that_cannot_be_meant_is_refused_naming_the_field(grasp: dict, field: str):
    def source(crop: dict) -> list:
        return [{"center_px": (112, 112), "angle": 0.3, "width_px": 60, **grasp}]

    with pytest.raises(lgdm.LgdmError, match=rf"source.*grasp 0: `{field}`"):
        lgdm.sim.grasp(grasp=source, rounds=1)


def test_a_grasp_at_the_limits_is_accepted():
    def source(crop: dict) -> list:
        side = crop["rgb"].shape[0]
        return [{"center_px": (-side + 1, 2 * side - 1), "angle": -999.0, "width_px": 4 * side,
                 "jaw_px": 0.5, "quality": 0}]  # fmt: skip

    r = lgdm.sim.grasp(grasp=source, rounds=1)
    assert r["summary"]["attempts"] >= 1


def test_a_failing_view_encoder_names_itself():
    def broken_encoder(points, colors):
        raise ValueError("no weights")

    with pytest.raises(lgdm.LgdmError, match=r"view encoder .*broken_encoder.*no weights") as e:
        lgdm.sim.pick_place(attempts=1, seed=1, encoder=(broken_encoder, 4))
    assert isinstance(e.value.__cause__, ValueError)


@pytest.mark.parametrize("writer", ["sim", "train"])
def test_force_never_clears_a_users_files(writer: str, tmp_path: Path, small_dataset):
    """A directory holding a user's pictures (or anything a run does not write by that exact
    name) is refused with force, and left as it was."""
    p = tmp_path / "p"
    p.mkdir()
    for name in ("holiday.png", ".draft.tmp", "nodes.png.bak"):
        (p / name).write_text("x")
    (p / "trials").mkdir()
    (p / "trials" / "holiday.png").write_text("x")
    before = sorted(str(f.relative_to(p)) for f in p.rglob("*"))
    for name in ("holiday.png", ".draft.tmp", "nodes.png.bak", "trials"):
        with pytest.raises(lgdm.LgdmError, match="not part of"):
            if writer == "sim":
                lgdm.sim.grasp(rounds=1, out=p, force=True)
            else:
                lgdm.run_scenario(lgdm.good_features(small_dataset), "ni", trials=1, out=p,
                                  force=True)  # fmt: skip
        assert sorted(str(f.relative_to(p)) for f in p.rglob("*")) == before
        target = p / name
        if target.is_dir():
            (target / "holiday.png").unlink()
            target.rmdir()
        else:
            target.unlink()
        before = sorted(str(f.relative_to(p)) for f in p.rglob("*"))
    # Nothing of the user's left: the directory is used.
    if writer == "sim":
        lgdm.sim.grasp(rounds=1, out=p, force=True)
        assert (p / "results.json").is_file()
    else:
        lgdm.run_scenario(lgdm.good_features(small_dataset), "ni", trials=1, out=p, force=True)
        assert (p / "metrics.json").is_file()


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"scenario": "nowhere"}, "scenario"),
        ({"grasp": "psychic"}, "psychic"),
        ({"grasp": "network"}, "network"),
        ({"gripper": "2f-300"}, "gripper"),
        ({"rounds": 0}, "rounds"),
    ],
)
def test_bad_settings_are_config_errors_naming_them(kwargs: dict, field: str):
    with pytest.raises(lgdm.ConfigError, match=field):
        lgdm.sim.grasp(**kwargs)


def test_pick_place_and_packing_recognise_and_place():
    r = lgdm.sim.pick_place(attempts=4, seed=1)
    s = r["summary"]
    assert s["attempts"] == 4
    assert s["recognition_accuracy"] is not None
    p = lgdm.sim.packing(["mug", "can"], rounds=1, seed=1)
    assert "packing" in p["summary"]
    with pytest.raises(lgdm.LgdmError, match="spaceship"):
        lgdm.sim.packing(["spaceship"], rounds=1)


CLI_ONLY = {"resume", "help", "ae-checkpoint", "progress"}


@pytest.mark.parametrize(
    "command, function",
    [
        ("grasp", lgdm.sim.grasp),
        ("pick-place", lgdm.sim.pick_place),
        ("packing", lgdm.sim.packing),
    ],
)
def test_keywords_are_the_command_lines_options(command: str, function):
    cli = _find_cli()
    if cli is None:
        pytest.skip("the lgdm binary is not built (cargo build --release -p lgdm-cli)")
    text = subprocess.run(
        [str(cli), "sim", command, "--help"], capture_output=True, text=True, check=True
    ).stdout
    options = set(re.findall(r"^\s+(?:-\w, )?--([a-z][a-z0-9-]*)", text, re.M)) - CLI_ONLY
    keywords = {
        {"replay": "no-replay"}.get(name, name.replace("_", "-"))
        for name in inspect.signature(function).parameters
    } - {"progress"}
    assert keywords == options, f"Python only: {keywords - options}, CLI only: {options - keywords}"


@pytest.mark.parametrize("option", ["gripper", "draw", "shapes", "proposal_check"])
def test_typed_words_are_the_command_lines(option: str):
    """The `Literal` words of `gripper`, `draw`, `shapes` and `proposal_check` are the ones
    `lgdm_sim` spells (the CLI's possible values, from `OptionValue`)."""
    flag = option.replace("_", "-")
    cli = _find_cli()
    if cli is None:
        pytest.skip("the lgdm binary is not built (cargo build --release -p lgdm-cli)")
    text = subprocess.run(
        [str(cli), "sim", "pick-place", "--help"], capture_output=True, text=True, check=True
    ).stdout
    block = re.search(rf"--{flag} <\w+>\n(.*?)\n\n\s+--", text, re.S)
    assert block, text
    words = re.findall(r"^\s+- ([\w-]+):", block.group(1), re.M)
    for function in (lgdm.sim.grasp, lgdm.sim.pick_place, lgdm.sim.packing):
        hint = typing.get_type_hints(function)[option]
        (literal,) = [a for a in typing.get_args(hint) if typing.get_origin(a) is typing.Literal]
        assert sorted(typing.get_args(literal)) == sorted(words), function.__name__
        with pytest.raises(lgdm.ConfigError, match=f"{flag}: unknown `nope`"):
            targets = {"targets": ["mug"]} if function is lgdm.sim.packing else {}
            function(**targets, **{option: "nope"}, rounds=1)


def test_the_same_run_as_the_command_line(tmp_path: Path):
    cli = _find_cli()
    if cli is None:
        pytest.skip("the lgdm binary is not built (cargo build --release -p lgdm-cli)")
    args = ["--scenario", "packed", "--rounds", "1", "--seed", "3", "--gripper", "2f-85"]
    subprocess.run(
        [str(cli), "sim", "grasp", *args, "--progress", "none", "--out", str(tmp_path / "cli")],
        capture_output=True,
        check=True,
    )
    r = lgdm.sim.grasp(scenario="packed", rounds=1, seed=3, gripper="2f-85", out=tmp_path / "py")
    cli_results = json.loads((tmp_path / "cli" / "results.json").read_text())
    assert without_wall(cli_results) == without_wall(r)
    assert (tmp_path / "cli" / "sim.toml").read_text() == (tmp_path / "py" / "sim.toml").read_text()
    # The same pictures, drawn by the library for both.
    pictures = sorted(p.name for p in (tmp_path / "cli").glob("*.png"))
    assert pictures == ["failure_reasons.png", "success_by_category.png"]
    for name in pictures:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


def counting_source(fail_at: int | None):
    """A source that finds nothing, failing at its `fail_at`-th call (a crash mid-run)."""
    calls = []

    def source(crop: dict) -> list:
        calls.append(1)
        if fail_at is not None and len(calls) == fail_at:
            raise RuntimeError("interrupted")
        return []

    return source


def test_an_interrupted_run_resumes_to_the_uninterrupted_results(tmp_path: Path):
    straight = lgdm.sim.grasp(grasp=counting_source(None), rounds=4, seed=2, out=tmp_path / "a")
    with pytest.raises(lgdm.LgdmError, match="interrupted"):
        lgdm.sim.grasp(grasp=counting_source(5), rounds=4, seed=2, out=tmp_path / "b")
    assert not (tmp_path / "b" / "results.json").exists()
    with pytest.raises(lgdm.ConfigError, match="pass it again"):
        lgdm.sim.resume(tmp_path / "b")
    resumed = lgdm.sim.resume(tmp_path / "b", grasp=counting_source(None))
    assert without_wall(resumed) == without_wall(straight)
    a = json.loads((tmp_path / "a" / "results.json").read_text())
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    assert without_wall(a) == without_wall(b)


def test_a_pick_place_run_resumes_from_its_record(tmp_path: Path):
    straight = lgdm.sim.pick_place(rounds=2, seed=4, out=tmp_path / "a")
    (tmp_path / "a" / "results.json").unlink()
    resumed = lgdm.sim.resume(tmp_path / "a")
    assert without_wall(resumed) == without_wall(straight)
    pictures = {p.name for p in (tmp_path / "a").glob("*.png")}
    assert {"learning_curve.png", "nodes.png", "success_by_category.png"} <= pictures


def test_a_python_view_encoder_recognises_in_the_loop(tmp_path: Path):
    views = []

    def extent(points: np.ndarray, colors: np.ndarray | None) -> np.ndarray:
        views.append((points.shape, None if colors is None else colors.dtype))
        lo, hi = points.min(axis=0), points.max(axis=0)
        return np.concatenate([hi - lo, points.mean(axis=0)])

    r = lgdm.sim.pick_place(attempts=4, seed=1, encoder=(extent, 6), out=tmp_path / "run")
    assert views and views[0][0][1] == 3
    assert r["summary"]["recognition_accuracy"] is not None
    name = r["recognition"]["encoder"]
    assert name.startswith("python:") and name.endswith(".extent"), name

    def wrong_length(points, colors):
        return [1.0, 2.0]

    with pytest.raises(lgdm.LgdmError, match="2 values, not the 6"):
        lgdm.sim.pick_place(attempts=2, seed=1, encoder=(wrong_length, 6))
    with pytest.raises(lgdm.ConfigError, match="encoder"):
        lgdm.sim.pick_place(attempts=2, encoder="fancy")


@pytest.fixture
def python_sigint():
    """SIGINT handled by Python's own handler (``KeyboardInterrupt``), as in a plain ``python``
    process: ``_thread.interrupt_main`` does nothing under another handler, and a library loaded
    earlier in the test process (e.g. by collecting the Ray tests) may have installed one."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_ctrl_c_stops_a_run_with_whole_rounds_written_and_it_resumes(
    tmp_path: Path, python_sigint: None
):
    """Ctrl-C (here ``_thread.interrupt_main`` from the source, as a signal would arrive) stops
    the run; its directory holds whole rounds, and resuming gives the results of the run never
    stopped."""
    import _thread

    def make(interrupt_at: int | None):
        calls = []

        def source(crop: dict) -> list:
            calls.append(1)
            if len(calls) == interrupt_at:
                _thread.interrupt_main()
            return []

        return source

    straight = lgdm.sim.grasp(grasp=make(None), rounds=4, seed=6, out=tmp_path / "a")
    with pytest.raises(KeyboardInterrupt):
        lgdm.sim.grasp(grasp=make(5), rounds=4, seed=6, out=tmp_path / "b")
    assert not (tmp_path / "b" / "results.json").exists()
    resumed = lgdm.sim.resume(tmp_path / "b", grasp=make(None))
    assert without_wall(resumed) == without_wall(straight)


def test_ctrl_c_while_rust_works_stops_after_the_round(tmp_path: Path, python_sigint: None):
    """A Ctrl-C arriving while the analytic source and the physics run (the GIL released) stops
    the run after its round, checkpointed; resuming finishes it as if never stopped."""
    import _thread
    import threading

    straight = lgdm.sim.grasp(rounds=5, seed=8, out=tmp_path / "a")
    threading.Timer(0.05, _thread.interrupt_main).start()
    with pytest.raises(KeyboardInterrupt):
        lgdm.sim.grasp(rounds=5, seed=8, out=tmp_path / "b")
    progress = json.loads((tmp_path / "b" / "progress.json").read_text())
    assert 1 <= progress["state"]["rounds_done"] < 5
    assert not (tmp_path / "b" / "results.json").exists()
    resumed = lgdm.sim.resume(tmp_path / "b")
    assert without_wall(resumed) == without_wall(straight)
