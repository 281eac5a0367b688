"""The grasp convention shared with the Rust decoder, against the golden fixture the Rust side
writes: ``<repo>/tests/fixtures/grasp_convention.json`` (format ``lgdm.grasp-convention.v1``).

For every case: the angle of each rectangle (from its corners), the four label maps, and the
decoded grasps (with the case's jaw, or opening / 2 when it is null) must equal the fixture's.
A missing fixture is a failure, not a skip: the two implementations must not drift apart
silently.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from train_ae.grasp import (
    LABEL_CENTRE_FRACTION,
    PEAK_MIN_DISTANCE_PX,
    QUALITY_SIGMA_PX,
    QUALITY_THRESHOLD,
    WIDTH_SCALE_PX,
    WIDTH_SIGMA_PX,
    GraspRectangle,
    angle_difference,
    decode_grasps,
    grasp_maps,
)

FIXTURE = Path(__file__).resolve().parents[3] / "tests" / "fixtures" / "grasp_convention.json"
FORMAT = "lgdm.grasp-convention.v1"
MISSING = "<fixture missing>"


def _fixture() -> dict:
    if not FIXTURE.is_file():
        pytest.fail(f"golden grasp-convention fixture {FIXTURE} does not exist: the Rust side "
                    f"writes it (format {FORMAT}); without it the Python and Rust grasp "
                    f"conventions are not checked against each other", pytrace=False)
    try:
        data = json.loads(FIXTURE.read_text())
    except (OSError, json.JSONDecodeError) as e:
        pytest.fail(f"{FIXTURE}: not readable JSON: {e}", pytrace=False)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        pytest.fail(f"{FIXTURE}: format is not {FORMAT!r}", pytrace=False)
    return data


def _case_names() -> list[str]:
    try:
        names = [c["name"] for c in json.loads(FIXTURE.read_text())["cases"]]
    except (OSError, ValueError, KeyError, TypeError):
        return [MISSING]  # each test then fails with the reason
    return names or [MISSING]


def _case(name: str) -> dict:
    data = _fixture()
    cases = data.get("cases") or []
    if not cases:
        pytest.fail(f"{FIXTURE}: no cases", pytrace=False)
    for c in cases:
        if c.get("name") == name:
            return c
    pytest.fail(f"{FIXTURE}: no case named {name!r}", pytrace=False)


def _rects(case: dict) -> list[GraspRectangle]:
    return [GraspRectangle.from_corners(np.array(r, dtype=np.float64))
            for r in case["rectangles"]]


def test_constants_match_the_fixture():
    conv = _fixture()["convention"]
    # The fixture holds f32 values (Rust), hence the tolerance.
    assert WIDTH_SCALE_PX == pytest.approx(conv["width_scale_px"], rel=1e-6)
    assert LABEL_CENTRE_FRACTION == pytest.approx(conv["label_centre_fraction"], rel=1e-6)
    assert QUALITY_THRESHOLD == pytest.approx(conv["quality_threshold"], rel=1e-6)
    assert conv["min_distance_px"] == PEAK_MIN_DISTANCE_PX
    assert QUALITY_SIGMA_PX == pytest.approx(conv["quality_sigma_px"], rel=1e-6)
    assert WIDTH_SIGMA_PX == pytest.approx(conv["width_sigma_px"], rel=1e-6)


@pytest.mark.parametrize("name", _case_names())
def test_rectangle_angles(name):
    case = _case(name)
    rects = _rects(case)
    assert len(rects) == len(case["angles"])
    for i, (r, a) in enumerate(zip(rects, case["angles"], strict=True)):
        assert angle_difference(r.angle, a) <= 1e-5, (name, i, r.angle, a)


@pytest.mark.parametrize("name", _case_names())
def test_label_maps(name):
    case = _case(name)
    rows, cols = case["rows"], case["cols"]
    maps = grasp_maps(_rects(case), (rows, cols))
    for key, got in zip(("quality", "cos2t", "sin2t", "width"), maps, strict=True):
        want = np.asarray(case["maps"][key], dtype=np.float64).reshape(rows, cols)
        bad = np.argwhere(np.abs(got - want) > 1e-6)
        assert not len(bad), (f"{name}: {key} differs at {len(bad)} pixels, first (row, col) "
                              f"{bad[0].tolist()}: {got[tuple(bad[0])]} vs {want[tuple(bad[0])]}")


@pytest.mark.parametrize("name", _case_names())
def test_decoding(name):
    case = _case(name)
    rows, cols = case["rows"], case["cols"]
    maps = [np.asarray(case["maps"][k], dtype=np.float32).reshape(rows, cols)
            for k in ("quality", "cos2t", "sin2t", "width")]
    got = decode_grasps(*maps, num_grasps=case["num_grasps"], jaw_px=case["jaw_px"])
    want = case["decoded"]
    assert len(got) == len(want), (name, [(g.center_x, g.center_y) for g in got])
    for i, (g, w) in enumerate(zip(got, want, strict=True)):
        where = f"{name}: grasp {i}"
        assert (g.center_x, g.center_y) == pytest.approx(tuple(w["center_px"]), abs=1e-3), where
        assert angle_difference(g.angle, w["angle"]) <= 1e-4, (where, g.angle, w["angle"])
        assert g.width_px == pytest.approx(w["width_px"], abs=1e-3), where
        assert g.jaw_px == pytest.approx(w["jaw_px"], abs=1e-3), where
        # Quality: the smoothed map at the decoded pixel.
        assert _quality(maps[0], g) == pytest.approx(w["quality"], abs=1e-5), where


def _quality(quality: np.ndarray, g: GraspRectangle) -> float:
    from train_ae.grasp import gaussian_smooth

    q = gaussian_smooth(quality, QUALITY_SIGMA_PX).numpy()
    return float(q[round(g.center_y), round(g.center_x)])


def test_fixture_covers_the_hard_cases():
    """Rim pinches (openings of a few pixels), angles near ±90°, an image with no grasp."""
    cases = _fixture()["cases"]
    rects = [r for c in cases for r in _rects(c)]
    assert any(r.width_px <= 5 for r in rects), "no thin rim-pinch rectangle"
    assert any(abs(abs(r.angle) - math.pi / 2) < math.radians(5) for r in rects), \
        "no angle near ±90°"
    assert any(not c["decoded"] for c in cases), "no case without a decoded grasp"
