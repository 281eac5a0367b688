"""``lgdm.sim``: the simulated robot — ``lgdm sim grasp``, ``pick-place`` and ``packing`` as
calls, with the command line's options as keyword arguments.

Each call plays the run in Rust (the ``lgdm-sim`` library the binary runs; the GIL is released)
and returns its results as ``results.json`` holds them: ``result["summary"]`` (the rates, each
with its Wilson interval), ``result["attempts"]`` (one dict per attempt), ``result["rounds"]``,
``result["config"]`` and the wall times. With ``out=`` it writes the same run directory as the
command line (job record, ``sim.toml``, per-round checkpoints, ``results.json``,
``summary.txt`` and the plots).

**Grasp sources.** ``grasp`` is ``"analytic"`` (default), ``"random"``, or a callable that
proposes grasps — how you try your own network on the robot. It is called once per look at an
object with one argument, the robot's crop, a dict of:

- ``rgb``: ``(S, S, 3)`` uint8 and ``depth``: ``(S, S)`` float32, metres along the camera's axis
  (0 where there is no data) — the object-centred crop (``S`` = 224 by default), the camera
  looking straight down;
- ``focal_px``: the crop's focal length in crop pixels — a crop pixel at depth ``d`` spans
  ``d / focal_px`` metres; ``table_depth_m``: the table's depth at the crop's centre;
- ``stroke_m`` and ``finger_width_m``: the gripper;
- ``max_grasps``: how many of the returned grasps the robot looks at (the first ones);
- ``decode``: the run's decoder settings (``[attempt.decode]``: ``quality_threshold``,
  ``min_distance_px``, ``quality_sigma_px``, ``width_sigma_px``), for :func:`decode_grasps`.

It returns a list (best first; empty: no grasp found) of dicts in the grasp decoders'
convention: ``center_px`` ``(x, y)`` (x the column, y the row, crop pixels), ``angle`` (the
opening axis, radians counter-clockwise on screen from +x; taken modulo π), ``width_px`` (the
opening, crop pixels) and optionally ``jaw_px`` (the jaws' extent across it; default the finger
width at the table's depth) and ``quality`` (default 1). The robot plans and executes the first
that it can place in the world and whose pads close on something, as it does with the built-in
sources. A network giving the grasp autoencoder's four maps can decode them with
:func:`decode_grasps`, as ``--grasp network`` does (``examples/python/network_grasps.py``
wraps ``train_ae``'s network so). An exception in the
callable stops the run with an :class:`LgdmError` naming the callable, the exception as its
cause.

Example::

    import lgdm.sim

    result = lgdm.sim.grasp(scenario="isolated", rounds=3, seed=11)
    print(result["summary"]["grasp_success_rate"]["value"])

    def nothing(crop):
        return []  # a source that never finds a grasp

    assert lgdm.sim.grasp(grasp=nothing, rounds=2)["summary"]["grasp_success_rate"]["value"] == 0
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from os import PathLike
from typing import Any, Literal

from . import _lgdm

__all__ = [
    "GraspSource",
    "Progress",
    "ViewEncoder",
    "decode_grasps",
    "grasp",
    "packing",
    "pick_place",
    "resume",
]

#: A grasp source: ``"analytic"``, ``"random"``, or a callable from the robot's crop to a list
#: of grasps (see the module's docs).
GraspSource = Literal["analytic", "random"] | Callable[[dict[str, Any]], list[dict[str, Any]]]

#: A view encoder for recognition: ``"good"`` (GOOD, 675 values), or ``(callable, dim)``: the
#: callable gets one view — its points ``(N, 3)`` float32 in metres in the camera's optical
#: frame, and their colours ``(N, 3)`` uint8 or ``None`` — and returns ``dim`` numbers (or
#: ``None`` for a view it cannot describe).
ViewEncoder = Literal["good"] | tuple[Callable[[Any, Any], Any], int]

#: A progress callback: ``(stage, done, total)``, e.g. ``("rounds", 3, 10)``.
Progress = Callable[[str, int, int], object]

Path = str | PathLike[str]


def _path(p: Path | None) -> str | None:
    return None if p is None else str(p)


def _units(units: str | Sequence[str] | None) -> list[str]:
    if units is None:
        return []
    return [units] if isinstance(units, str) else [str(u) for u in units]


def grasp(
    *,
    scenario: Literal["isolated", "packed", "pile", "scattered"] = "isolated",
    grasp: GraspSource = "analytic",
    rounds: int = 10,
    seed: int = 0,
    instances: int = 5,
    meshes: Path | None = None,
    units: str | Sequence[str] | None = None,
    config: Path | None = None,
    gripper: Literal["2f-140", "2f-85"] | None = None,
    draw: Literal["collider", "mesh"] | None = None,
    shapes: Literal["decomposition", "hull"] | None = None,
    proposal_check: Literal["contacts", "antipodal", "refine", "refine-first",
                            "refine-ranked"] | None = None,
    out: Path | None = None,
    force: bool = False,
    record: bool = False,
    record_rounds: int | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """``lgdm sim grasp``: grasp trials, each grasped object carried to the basket.

    The options are the command line's (``lgdm sim grasp --help``): ``instances`` procedural
    objects per category from ``seed``, or the meshes under ``meshes`` (with ``units``, e.g.
    ``"mm"`` or ``["m", "cat/file.stl=mm"]``); ``config`` a ``sim.toml`` (a run directory's
    replays that run) with ``gripper``, ``draw``, ``shapes`` and ``proposal_check`` on top.
    Returns the results as ``results.json`` holds them; ``out`` also writes the run directory.
    """
    text = _lgdm.sim_grasp(
        scenario_name=scenario,
        grasp=grasp,
        rounds=rounds,
        seed=seed,
        instances=instances,
        meshes=_path(meshes),
        units=_units(units),
        config_file=_path(config),
        gripper=gripper,
        draw=draw,
        shapes=shapes,
        proposal_check=proposal_check,
        out=_path(out),
        force=force,
        record_all=record,
        record_rounds=record_rounds,
        progress=progress,
    )
    return json.loads(text)


def pick_place(
    *,
    scenario: Literal["scattered", "packed", "pile"] = "scattered",
    grasp: GraspSource = "analytic",
    rounds: int | None = None,
    attempts: int | None = None,
    seed: int = 0,
    objects: int = 15,
    object_seed: int = 0,
    meshes: Path | None = None,
    units: str | Sequence[str] | None = None,
    model: Path | None = None,
    replay: bool = True,
    learn_always: bool = False,
    encoder: ViewEncoder = "good",
    confidence: float = 0.6,
    arrive_after: int | None = None,
    config: Path | None = None,
    gripper: Literal["2f-140", "2f-85"] | None = None,
    draw: Literal["collider", "mesh"] | None = None,
    shapes: Literal["decomposition", "hull"] | None = None,
    proposal_check: Literal["contacts", "antipodal", "refine", "refine-first",
                            "refine-ranked"] | None = None,
    out: Path | None = None,
    force: bool = False,
    record: bool = False,
    record_rounds: int | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """``lgdm sim pick-place``: the paper's pick-and-place — the robot recognises each object
    (GOOD features, the dual memory learning from a teacher), grasps it and puts it in the
    basket.

    The options are the command line's (``lgdm sim pick-place --help``); ``replay=False`` is
    ``--no-replay``; ``encoder`` is ``"good"`` or your own feature, ``(callable, dim)``
    (:data:`ViewEncoder`). ``rounds`` defaults to as many as ``attempts`` when that is given, else
    10. Returns the results as ``results.json`` holds them; ``out`` also writes the run
    directory with the learnt ``model.lgdm``.
    """
    return _recognition_run(
        None,
        scenario=scenario,
        grasp=grasp,
        rounds=rounds,
        attempts=attempts,
        seed=seed,
        objects=objects,
        object_seed=object_seed,
        meshes=meshes,
        units=units,
        model=model,
        replay=replay,
        learn_always=learn_always,
        encoder=encoder,
        confidence=confidence,
        arrive_after=arrive_after,
        config=config,
        gripper=gripper,
        draw=draw,
        shapes=shapes,
        proposal_check=proposal_check,
        out=out,
        force=force,
        record=record,
        record_rounds=record_rounds,
        progress=progress,
    )


def packing(
    targets: Sequence[str],
    *,
    scenario: Literal["scattered", "packed", "pile"] = "scattered",
    grasp: GraspSource = "analytic",
    rounds: int | None = None,
    attempts: int | None = None,
    seed: int = 0,
    objects: int = 15,
    object_seed: int = 0,
    meshes: Path | None = None,
    units: str | Sequence[str] | None = None,
    model: Path | None = None,
    replay: bool = True,
    learn_always: bool = False,
    encoder: ViewEncoder = "good",
    confidence: float = 0.6,
    arrive_after: int | None = None,
    config: Path | None = None,
    gripper: Literal["2f-140", "2f-85"] | None = None,
    draw: Literal["collider", "mesh"] | None = None,
    shapes: Literal["decomposition", "hull"] | None = None,
    proposal_check: Literal["contacts", "antipodal", "refine", "refine-first",
                            "refine-ranked"] | None = None,
    out: Path | None = None,
    force: bool = False,
    record: bool = False,
    record_rounds: int | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """``lgdm sim packing``: pick-and-place's options and ``targets``, the categories packed
    into the right basket (everything else into the left one). ``rounds`` defaults to 50 when
    ``attempts`` is not given.
    """
    if isinstance(targets, str):
        targets = [t for t in targets.split(",") if t]
    return _recognition_run(
        [str(t) for t in targets],
        scenario=scenario,
        grasp=grasp,
        rounds=rounds,
        attempts=attempts,
        seed=seed,
        objects=objects,
        object_seed=object_seed,
        meshes=meshes,
        units=units,
        model=model,
        replay=replay,
        learn_always=learn_always,
        encoder=encoder,
        confidence=confidence,
        arrive_after=arrive_after,
        config=config,
        gripper=gripper,
        draw=draw,
        shapes=shapes,
        proposal_check=proposal_check,
        out=out,
        force=force,
        record=record,
        record_rounds=record_rounds,
        progress=progress,
    )


def resume(
    run_dir: Path,
    *,
    grasp: GraspSource | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Finishes the interrupted run in ``run_dir`` with its own settings, as ``lgdm sim …
    --resume`` does: the rounds it finished are kept, the rest are played, and the results, model
    and recordings equal those of a run never stopped. ``grasp`` defaults to the source the
    run's record names; a run that used a Python callable needs it again (the same
    ``__qualname__``).
    """
    return json.loads(_lgdm.sim_resume(str(run_dir), grasp=grasp, progress=progress))


def decode_grasps(
    quality: Any,
    cos2t: Any,
    sin2t: Any,
    width: Any,
    *,
    num_grasps: int = 1,
    jaw_side_fraction: float | None = None,
    crop_px: int | None = None,
    decode: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """The grasp autoencoder's maps — quality, cos 2θ, sin 2θ and width, each ``(H, H)`` float32
    at the network's input size — decoded as ``python -m train_ae.evaluate`` decodes them: at
    most ``num_grasps`` grasps, best first, with the checkpoint's jaw (``jaw_side_fraction``,
    ``train_ae.bridge.jaw_side_fraction``; ``None``: half the opening), in the pixels of the
    ``crop_px``-side crop the input was resized from (default: the maps' own). The dicts are a
    grasp callable's answer (the module's docs); it is the Rust decoder ``--grasp network``
    uses, so a callable wrapping the network with it gives the robot the same grasps. Pass the
    crop's ``decode`` (the run's ``[attempt.decode]``) to decode with the run's threshold, peak
    window and smoothing, as ``--grasp network`` does; without it, train_ae's defaults.
    """
    return _lgdm.sim_decode_grasps(
        quality,
        cos2t,
        sin2t,
        width,
        num_grasps=num_grasps,
        jaw_side_fraction=jaw_side_fraction,
        crop_px=crop_px,
        decode=decode,
    )


def _recognition_run(
    targets: list[str] | None,
    *,
    scenario: str,
    grasp: GraspSource,
    rounds: int | None,
    attempts: int | None,
    seed: int,
    objects: int,
    object_seed: int,
    meshes: Path | None,
    units: str | Sequence[str] | None,
    model: Path | None,
    replay: bool,
    learn_always: bool,
    encoder: ViewEncoder,
    confidence: float,
    arrive_after: int | None,
    config: Path | None,
    gripper: str | None,
    draw: str | None,
    shapes: str | None,
    proposal_check: str | None,
    out: Path | None,
    force: bool,
    record: bool,
    record_rounds: int | None,
    progress: Progress | None,
) -> dict[str, Any]:
    text = _lgdm.sim_pick_place(
        scenario_name=scenario,
        grasp=grasp,
        rounds=rounds,
        attempts=attempts,
        seed=seed,
        objects_n=objects,
        object_seed=object_seed,
        meshes=_path(meshes),
        units=_units(units),
        model=_path(model),
        replay=replay,
        learn_always=learn_always,
        encoder=encoder,
        confidence=confidence,
        targets=targets,
        arrive_after=arrive_after,
        config_file=_path(config),
        gripper=gripper,
        draw=draw,
        shapes=shapes,
        proposal_check=proposal_check,
        out=_path(out),
        force=force,
        record_all=record,
        record_rounds=record_rounds,
        progress=progress,
    )
    return json.loads(text)
