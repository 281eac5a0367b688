"""Grasp rectangles: exact polygon IoU, the rectangle metric at its thresholds, label maps and
decoding them back (round trip). (The Wilson interval: test_wilson.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from train_ae.grasp import (
    JAW_FRACTION,
    WIDTH_SCALE_PX,
    GraspRectangle,
    angle_difference,
    decode_grasps,
    grasp_maps,
    is_correct,
    jaw_px_for,
    negative_map,
    polygon_iou,
    rectangle_iou,
)

deg = math.radians


def shifted(r: GraspRectangle, along: float) -> GraspRectangle:
    """``r`` moved by ``along`` pixels along its own opening axis."""
    dx, dy = math.cos(r.angle) * along, -math.sin(r.angle) * along
    return GraspRectangle(r.center_x + dx, r.center_y + dy, r.angle, r.width_px, r.jaw_px)


def test_corners_round_trip_and_angle_convention():
    # Opening axis pointing right and up on screen (y grows downwards): positive angle.
    corners = np.array([[10, 20], [20, 10], [25, 15], [15, 25]], float)
    r = GraspRectangle.from_corners(corners)
    assert r.angle == pytest.approx(deg(45))
    assert r.width_px == pytest.approx(math.hypot(10, 10))
    assert r.jaw_px == pytest.approx(math.hypot(5, 5))
    assert (r.center_x, r.center_y) == pytest.approx((17.5, 17.5))
    np.testing.assert_allclose(r.corners(), corners, atol=1e-9)
    # Opening axis reversed (corner order 1, 0, 3, 2): same grasp, same angle modulo π.
    r2 = GraspRectangle.from_corners(corners[[1, 0, 3, 2]])
    assert angle_difference(r.angle, r2.angle) == pytest.approx(0, abs=1e-12)
    assert -math.pi / 2 <= r2.angle < math.pi / 2


def test_polygon_iou_simple_cases():
    sq = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    assert polygon_iou(sq, sq) == pytest.approx(1.0)
    assert polygon_iou(sq, sq + np.array([20, 0])) == 0.0
    assert polygon_iou(sq, sq + np.array([5, 0])) == pytest.approx(50 / 150)
    # Either vertex orientation.
    assert polygon_iou(sq, sq[::-1] + np.array([5, 5])) == pytest.approx(25 / 175)
    diamond = np.array([[5, -2], [12, 5], [5, 12], [-2, 5]], float)
    # Square corners cut off by the diamond: area inside = 100 - 4 * (0.5 * 3 * 3) = 82.
    assert polygon_iou(sq, diamond) == pytest.approx(82 / (100 + 98 - 82))


def test_polygon_iou_matches_dense_sampling_for_rotated_rectangles():
    rng = np.random.default_rng(1)
    g = (np.arange(800) + 0.5) / 800 * 80 - 20  # 0.1 px grid over [-20, 60]
    xs, ys = np.meshgrid(g, g)

    def inside(r):
        c = r.corners()
        m = np.ones(xs.shape, bool)
        for i in range(4):
            (ax, ay), (bx, by) = c[i], c[(i + 1) % 4]
            # corners() has a positive shoelace area: the inside is left of every edge.
            m &= (bx - ax) * (ys - ay) - (by - ay) * (xs - ax) >= 0
        return m

    for _ in range(5):
        a = GraspRectangle(*rng.uniform(15, 25, 2), rng.uniform(-1.5, 1.5), *rng.uniform(8, 30, 2))
        b = GraspRectangle(*rng.uniform(15, 25, 2), rng.uniform(-1.5, 1.5), *rng.uniform(8, 30, 2))
        ma, mb = inside(a), inside(b)
        sampled = (ma & mb).sum() / (ma | mb).sum()
        assert rectangle_iou(a, b) == pytest.approx(sampled, abs=0.01)


@pytest.mark.parametrize("angle", [0.0, deg(37)])
def test_iou_just_above_and_below_a_quarter(angle):
    # Two 10x10 squares shifted by d along one side: IoU = 10(10-d) / (200 - 10(10-d)),
    # which is 0.25 at d = 6.
    gt = GraspRectangle(50, 50, angle, 10, 10)
    above, below = shifted(gt, 5.9), shifted(gt, 6.1)
    assert rectangle_iou(above, gt) == pytest.approx(41 / 159)
    assert rectangle_iou(below, gt) == pytest.approx(39 / 161)
    assert is_correct(above, [gt])
    assert not is_correct(below, [gt])


def test_angle_just_inside_and_outside_thirty_degrees():
    gt = GraspRectangle(50, 50, 0.0, 40, 20)
    inside = GraspRectangle(50, 50, deg(29.9), 40, 20)
    outside = GraspRectangle(50, 50, deg(30.1), 40, 20)
    assert rectangle_iou(outside, gt) > 0.25  # only the angle decides
    assert is_correct(inside, [gt])
    assert not is_correct(outside, [gt])
    assert is_correct(GraspRectangle(50, 50, deg(-29.9), 40, 20), [gt])
    assert not is_correct(GraspRectangle(50, 50, deg(-30.1), 40, 20), [gt])


def test_angles_wrap_around_at_plus_minus_ninety_degrees():
    gt = GraspRectangle(50, 50, deg(89), 40, 20)
    assert angle_difference(deg(89), deg(-89)) == pytest.approx(deg(2))
    assert is_correct(GraspRectangle(50, 50, deg(-89), 40, 20), [gt])
    gt80 = GraspRectangle(50, 50, deg(80), 40, 20)
    just_in = GraspRectangle(50, 50, deg(-70.1), 40, 20)   # 29.9° away through ±90°
    just_out = GraspRectangle(50, 50, deg(-69.9), 40, 20)  # 30.1° away
    assert rectangle_iou(just_out, gt80) > 0.25
    assert is_correct(just_in, [gt80])
    assert not is_correct(just_out, [gt80])


def test_correct_against_any_ground_truth():
    far = GraspRectangle(10, 10, 0.0, 20, 10)
    near = GraspRectangle(80, 80, 0.0, 20, 10)
    pred = GraspRectangle(81, 80, deg(10), 20, 10)
    assert not is_correct(pred, [far])
    assert is_correct(pred, [far, near])
    assert not is_correct(pred, [])


def test_label_maps_mark_the_centre_third():
    r = GraspRectangle(60, 40, 0.0, 60, 20)  # opening along x from 30 to 90
    q, c2, s2, w = grasp_maps([r], (80, 120))
    assert q[40, 60] == 1 and q[40, 69] == 1 and q[40, 51] == 1
    assert q[40, 71] == 0 and q[40, 49] == 0  # centre third spans x in [50, 70]
    assert q[31, 60] == 1 and q[29, 60] == 0  # full jaw extent: y in [30, 50]
    assert c2[40, 60] == pytest.approx(1) and s2[40, 60] == pytest.approx(0)
    assert w[40, 60] == pytest.approx(60 / WIDTH_SCALE_PX)
    assert q.sum() == pytest.approx(21 * 21)
    assert np.all(w[q == 0] == 0) and np.all(c2[q == 0] == 0)


def test_negative_map_marks_failures_where_no_positive_is():
    good = GraspRectangle(60, 40, 0.0, 60, 20)  # quality 1 at x in [50, 70], y in [30, 50]
    bad = GraspRectangle(75, 40, 0.0, 60, 20)   # centre third: x in [65, 85]
    q = grasp_maps([good], (80, 120))[0]
    neg = negative_map([bad], q)
    assert neg.dtype == np.float32 and neg.shape == q.shape
    assert neg[40, 80] == 1 and neg[40, 72] == 1
    assert neg[40, 68] == 0 and q[40, 68] == 1  # a positive wins where both label
    assert neg[40, 87] == 0 and neg[29, 80] == 0
    assert neg.sum() == pytest.approx(21 * 21 - 6 * 21)  # x 65..70 overlap the positive
    assert not negative_map([], q).any()


def test_label_maps_and_back_round_trip():
    truth = [
        GraspRectangle(25, 25, deg(0), 40, 20),
        GraspRectangle(85, 30, deg(60), 36, 16),
        GraspRectangle(30, 85, deg(-89), 45, 24),
        GraspRectangle(85, 85, deg(-35), 60, 30),
    ]
    maps = grasp_maps(truth, (112, 112))
    decoded = decode_grasps(*maps, num_grasps=10)
    assert len(decoded) == len(truth)
    for t in truth:
        d = min(decoded, key=lambda g: math.hypot(g.center_x - t.center_x,
                                                  g.center_y - t.center_y))
        assert math.hypot(d.center_x - t.center_x, d.center_y - t.center_y) <= 1.0
        assert angle_difference(d.angle, t.angle) < deg(1)
        assert d.width_px == pytest.approx(t.width_px, abs=1.0)
        assert is_correct(d, truth)


def test_decode_of_empty_maps_finds_nothing():
    z = np.zeros((64, 64), np.float32)
    assert decode_grasps(z, z, z, z) == []


def test_decoded_jaw_is_the_given_width_or_half_the_opening():
    gt = GraspRectangle(40, 40, deg(20), 30, 8)
    maps = grasp_maps([gt], (80, 80))
    (cornell,) = decode_grasps(*maps)
    assert cornell.jaw_px == pytest.approx(cornell.width_px * JAW_FRACTION)
    (lgdm,) = decode_grasps(*maps, jaw_px=8.0)
    assert lgdm.jaw_px == 8.0 and lgdm.width_px == cornell.width_px
    assert rectangle_iou(lgdm, gt) > rectangle_iou(cornell, gt)
    assert jaw_px_for(None, 112) is None and jaw_px_for(0.25, 112) == 28.0
    with pytest.raises(ValueError, match="jaw_px"):
        decode_grasps(*maps, jaw_px=0.0)
