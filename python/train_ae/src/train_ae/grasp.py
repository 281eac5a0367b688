"""Grasp rectangles, their pixel-wise label maps, decoding maps back to rectangles, the metric.

Conventions (shared with the Rust decoder):

* Image coordinates: ``x`` = column, ``y`` = row, both in pixels; pixel (row r, column c) has its
  centre at (x=c, y=r).
* A rectangle is four corners (x, y); the first edge (corner 0 -> corner 1) lies along the
  gripper's opening axis, its length is the opening ``width_px``; the second edge (1 -> 2) is the
  jaw extent ``jaw_px``. This is the Cornell ``cpos.txt`` layout.
* The grasp angle θ (radians) is the direction of the opening axis measured counter-clockwise as
  seen on screen from the +x axis: θ = atan2(-(y1 - y0), x1 - x0), wrapped to [-π/2, π/2).
  A parallel-jaw grasp is symmetric under θ -> θ + π, so maps encode cos 2θ and sin 2θ.
* Width maps hold ``width_px / WIDTH_SCALE_PX`` (clipped to [0, 1]); decoding multiplies back.
* Label maps use each rectangle's own jaw. A decoded rectangle's jaw is ``jaw_px`` pixels when
  given (lgdm data: every label's jaw is the finger width, ``jaw_side_fraction`` x map side),
  else ``JAW_FRACTION`` x its opening (GG-CNN's convention for the real Cornell set).

Example::

    from train_ae.grasp import GraspRectangle, grasp_maps, decode_grasps, is_correct

    gt = GraspRectangle(center_x=50, center_y=40, angle=0.3, width_px=30, jaw_px=15)
    q, c2, s2, w = grasp_maps([gt], (112, 112))
    best = decode_grasps(q, c2, s2, w, num_grasps=1, jaw_px=15)[0]
    assert is_correct(best, [gt])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

WIDTH_SCALE_PX = 150.0
"""Opening width (pixels at network input resolution) that maps to 1.0 in the width map."""

IOU_THRESHOLD = 0.25
"""A predicted rectangle must overlap a ground-truth one by more than this IoU."""

ANGLE_THRESHOLD = math.pi / 6
"""... and differ from it in angle by at most this (30°), modulo π."""

QUALITY_SIGMA_PX = 2.0
"""Gaussian smoothing of the quality, cos 2θ and sin 2θ maps before decoding."""

WIDTH_SIGMA_PX = 1.0
"""Gaussian smoothing of the width map before decoding."""

QUALITY_THRESHOLD = 0.2
"""Peaks of the smoothed quality map below this are not grasps (GG-CNN / GR-ConvNet value)."""

PEAK_MIN_DISTANCE_PX = 20
"""Minimum distance between two decoded grasp centres (local-maximum window radius)."""

JAW_FRACTION = 0.5
"""Without a known jaw (``jaw_px=None``, the real Cornell set) decoded rectangles get a jaw
extent of this fraction of their opening width (GG-CNN)."""

LABEL_CENTRE_FRACTION = 1.0 / 3.0
"""Label maps mark only this central fraction of each rectangle's opening axis (GG-CNN)."""


def wrap_angle(theta: float) -> float:
    """Wrap an angle to [-π/2, π/2): grasp angles are defined modulo π."""
    return (theta + math.pi / 2) % math.pi - math.pi / 2


def angle_difference(a: float, b: float) -> float:
    """Absolute difference of two grasp angles modulo π, in [0, π/2]."""
    return abs(wrap_angle(a - b))


@dataclass(frozen=True)
class GraspRectangle:
    """An antipodal parallel-jaw grasp in image pixels (see the module docs for conventions)."""

    center_x: float
    center_y: float
    angle: float
    """Opening-axis direction in radians, counter-clockwise on screen from +x, in [-π/2, π/2)."""
    width_px: float
    """Gripper opening: length of the first edge."""
    jaw_px: float
    """Jaw extent: length of the second edge."""

    @staticmethod
    def from_corners(corners: np.ndarray) -> GraspRectangle:
        """From a (4, 2) array of (x, y) corners, first edge along the opening axis."""
        p = np.asarray(corners, dtype=np.float64)
        if p.shape != (4, 2):
            raise ValueError(f"a grasp rectangle needs (4, 2) corners, got shape {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError(f"grasp rectangle corners must be finite, got {p.tolist()}")
        dx, dy = p[1] - p[0]
        cx, cy = p.mean(axis=0)
        return GraspRectangle(
            center_x=float(cx),
            center_y=float(cy),
            angle=wrap_angle(math.atan2(-dy, dx)),
            width_px=float(math.hypot(dx, dy)),
            jaw_px=float(np.hypot(*(p[2] - p[1]))),
        )

    def corners(self) -> np.ndarray:
        """(4, 2) float64 (x, y) corners; corner 0 -> 1 along the opening axis."""
        u = np.array([math.cos(self.angle), -math.sin(self.angle)]) * (self.width_px / 2)
        v = np.array([math.sin(self.angle), math.cos(self.angle)]) * (self.jaw_px / 2)
        c = np.array([self.center_x, self.center_y])
        return np.stack([c - u - v, c + u - v, c + u + v, c - u + v])

    def scaled_about_center(self, width_factor: float, jaw_factor: float) -> GraspRectangle:
        return GraspRectangle(self.center_x, self.center_y, self.angle,
                              self.width_px * width_factor, self.jaw_px * jaw_factor)


# --- exact polygon IoU ---------------------------------------------------------------------------

def polygon_area(poly: np.ndarray) -> float:
    """Signed shoelace area; positive for counter-clockwise vertices in a y-up frame."""
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _ccw(poly: np.ndarray) -> np.ndarray:
    return poly if polygon_area(poly) >= 0 else poly[::-1]


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Sutherland–Hodgman: the part of polygon ``subject`` inside convex polygon ``clip``."""
    clip = _ccw(np.asarray(clip, dtype=np.float64))
    out = [tuple(p) for p in np.asarray(subject, dtype=np.float64)]
    n = len(clip)
    for i in range(n):
        if not out:
            break
        ax, ay = clip[i]
        bx, by = clip[(i + 1) % n]
        ex, ey = bx - ax, by - ay

        def side(p: tuple[float, float], ax=ax, ay=ay, ex=ex, ey=ey) -> float:
            return ex * (p[1] - ay) - ey * (p[0] - ax)  # > 0: left of a->b, i.e. inside

        inp, out = out, []
        for j in range(len(inp)):
            cur, prev = inp[j], inp[j - 1]
            sc, sp = side(cur), side(prev)
            if sc >= 0:
                if sp < 0:
                    t = sp / (sp - sc)
                    out.append((prev[0] + t * (cur[0] - prev[0]), prev[1] + t * (cur[1] - prev[1])))
                out.append(cur)
            elif sp >= 0:
                t = sp / (sp - sc)
                out.append((prev[0] + t * (cur[0] - prev[0]), prev[1] + t * (cur[1] - prev[1])))
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def polygon_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Exact intersection over union of two convex polygons given as (k, 2) vertex arrays."""
    a = _ccw(np.asarray(a, dtype=np.float64))
    b = _ccw(np.asarray(b, dtype=np.float64))
    inter = abs(polygon_area(clip_convex(a, b)))
    union = abs(polygon_area(a)) + abs(polygon_area(b)) - inter
    return inter / union if union > 0 else 0.0


def rectangle_iou(a: GraspRectangle, b: GraspRectangle) -> float:
    return polygon_iou(a.corners(), b.corners())


def is_correct(pred: GraspRectangle, ground_truth: Sequence[GraspRectangle],
               iou_threshold: float = IOU_THRESHOLD,
               angle_threshold: float = ANGLE_THRESHOLD) -> bool:
    """The rectangle metric: IoU > 0.25 and angle difference ≤ 30° with any ground truth."""
    return any(
        angle_difference(pred.angle, gt.angle) <= angle_threshold
        and rectangle_iou(pred, gt) > iou_threshold
        for gt in ground_truth
    )


# --- label maps ----------------------------------------------------------------------------------

def grasp_maps(rectangles: Sequence[GraspRectangle], shape: tuple[int, int]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Training targets (quality, cos 2θ, sin 2θ, width), each float32 (H, W).

    Every positive rectangle, shrunk to the central third of its opening axis (full jaw extent),
    marks quality 1 and its angle and width at the pixels whose centres lie inside it; later
    rectangles overwrite earlier ones where they overlap. Elsewhere all maps are 0.
    """
    quality = np.zeros(shape, np.float32)
    cos2 = np.zeros(shape, np.float32)
    sin2 = np.zeros(shape, np.float32)
    width = np.zeros(shape, np.float32)
    for r in rectangles:
        for sl, inside in _label_pixels(r, shape):
            quality[sl][inside] = 1.0
            cos2[sl][inside] = math.cos(2 * r.angle)
            sin2[sl][inside] = math.sin(2 * r.angle)
            width[sl][inside] = min(max(r.width_px / WIDTH_SCALE_PX, 0.0), 1.0)
    return quality, cos2, sin2, width


def negative_map(negatives: Sequence[GraspRectangle], quality: np.ndarray) -> np.ndarray:
    """Float32 (H, W): 1 where a negative rectangle (a grasp that failed or was rejected) labels
    the pixels ``grasp_maps`` would mark for it, except where ``quality`` (the positives' map)
    is already positive; 0 elsewhere. The loss weighs these pixels' quality term by
    ``neg_weight`` (``train_ae.training.grasp_loss``): a known failure, not an untried spot."""
    mask = np.zeros(quality.shape, np.float32)
    for r in negatives:
        for sl, inside in _label_pixels(r, quality.shape):
            mask[sl][inside] = 1.0
    mask[quality > 0] = 0.0
    return mask


def _label_pixels(r: GraspRectangle, shape: tuple[int, int]):
    """The pixels a rectangle labels: those whose centres lie inside it shrunk to
    ``LABEL_CENTRE_FRACTION`` of its opening; yields at most one (slices, boolean mask)."""
    h, w = shape
    poly = _ccw(r.scaled_about_center(LABEL_CENTRE_FRACTION, 1.0).corners())
    x0 = max(math.floor(poly[:, 0].min()), 0)
    x1 = min(math.ceil(poly[:, 0].max()), w - 1)
    y0 = max(math.floor(poly[:, 1].min()), 0)
    y1 = min(math.ceil(poly[:, 1].max()), h - 1)
    if x0 > x1 or y0 > y1:
        return
    ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1].astype(np.float64)
    inside = np.ones(xs.shape, bool)
    for i in range(4):
        (ax, ay), (bx, by) = poly[i], poly[(i + 1) % 4]
        inside &= (bx - ax) * (ys - ay) - (by - ay) * (xs - ax) >= -1e-9
    yield (slice(y0, y1 + 1), slice(x0, x1 + 1)), inside


# --- decoding ------------------------------------------------------------------------------------

def gaussian_smooth(image: np.ndarray | torch.Tensor, sigma: float) -> torch.Tensor:
    """Separable Gaussian blur (truncated at 4σ, edge pixels replicated) of (H, W) or (N, H, W)."""
    t = torch.as_tensor(image, dtype=torch.float32)
    squeeze = t.ndim == 2
    t = t.reshape(-1, 1, *t.shape[-2:])
    if sigma > 0:
        radius = max(int(4 * sigma + 0.5), 1)
        k = torch.arange(-radius, radius + 1, dtype=torch.float32)
        k = torch.exp(-0.5 * (k / sigma) ** 2)
        k = k / k.sum()
        t = F.pad(t, (radius, radius, radius, radius), mode="replicate")
        t = F.conv2d(t, k.view(1, 1, 1, -1))
        t = F.conv2d(t, k.view(1, 1, -1, 1))
    return t[:, 0][0] if squeeze else t[:, 0]


def _smooth_sequential(image: np.ndarray, sigma: float) -> np.ndarray:
    """``gaussian_smooth`` of one (H, W) map, summed tap by tap in float32: along rows, then
    columns, each output the running sum over the kernel in order. The same operations in the
    same order as the Rust decoder (lgdm_pointcloud::grasp::decode), so both find the same
    peaks on flat tops, whatever torch's convolution does."""
    a = np.asarray(image, dtype=np.float32)
    if sigma <= 0:
        return a.copy()
    radius = max(int(4 * sigma + 0.5), 1)
    k = torch.arange(-radius, radius + 1, dtype=torch.float32)
    k = torch.exp(-0.5 * (k / sigma) ** 2)
    k = (k / k.sum()).numpy()
    rows, cols = a.shape
    # Tap j of output x reads x - radius + j, edge pixels replicated (clipped once, here).
    xi, yi = np.arange(cols) - radius, np.arange(rows) - radius
    tmp = np.zeros_like(a)
    for j, w in enumerate(k):
        tmp = tmp + w * a[:, np.clip(xi + j, 0, cols - 1)]
    out = np.zeros_like(a)
    for j, w in enumerate(k):
        out = out + w * tmp[np.clip(yi + j, 0, rows - 1), :]
    return out


def decode_grasps(quality: np.ndarray, cos2t: np.ndarray, sin2t: np.ndarray, width: np.ndarray,
                  num_grasps: int = 1, threshold: float = QUALITY_THRESHOLD,
                  min_distance_px: int = PEAK_MIN_DISTANCE_PX, jaw_px: float | None = None
                  ) -> list[GraspRectangle]:
    """Best grasps from one image's (H, W) maps, highest smoothed quality first.

    Smooths quality, cos 2θ and sin 2θ with σ = 2 px (the trigonometric maps, not the wrapped
    angle) and width with σ = 1 px, keeps local maxima of quality within ``min_distance_px``
    that reach ``threshold`` (a flat top counts once, at its mean position; other maxima
    within the window of an accepted one are dropped), and returns at most ``num_grasps``
    rectangles with θ = atan2(sin 2θ, cos 2θ) / 2, opening = width * WIDTH_SCALE_PX and
    jaw = ``jaw_px`` (the gripper's finger width in map pixels: lgdm data), or
    opening * JAW_FRACTION when ``jaw_px`` is None (the real Cornell set).
    """
    if jaw_px is not None and not (math.isfinite(jaw_px) and jaw_px > 0):
        raise ValueError(f"jaw_px must be a positive number or None, got {jaw_px!r}")
    q = _smooth_sequential(quality, QUALITY_SIGMA_PX)
    k = 2 * min_distance_px + 1
    local_max = F.max_pool2d(torch.from_numpy(q)[None, None], k, stride=1,
                             padding=min_distance_px)[0, 0]
    rows, cols = np.nonzero((q >= local_max.numpy()) & (q >= threshold))
    if len(rows) == 0:
        return []
    c = _smooth_sequential(cos2t, QUALITY_SIGMA_PX)
    s = _smooth_sequential(sin2t, QUALITY_SIGMA_PX)
    wd = _smooth_sequential(width, WIDTH_SIGMA_PX)
    # Highest score first; ties by row, then column (np.lexsort: last key is primary).
    scores = q[rows, cols]
    order = np.lexsort((cols, rows, -scores))
    out: list[GraspRectangle] = []
    taken = np.zeros(len(rows), bool)
    for i in order:
        if taken[i]:
            continue
        # A flat top (equal maxima within the window) is one peak at its mean position.
        near = ((np.abs(rows - rows[i]) <= min_distance_px)
                & (np.abs(cols - cols[i]) <= min_distance_px) & ~taken)
        twins = near & (scores >= scores[i] - 1e-6 * max(1.0, abs(float(scores[i]))))
        taken |= near
        cy, cx = float(rows[twins].mean()), float(cols[twins].mean())
        r, col = round(cy), round(cx)
        opening = float(wd[r, col]) * WIDTH_SCALE_PX
        out.append(GraspRectangle(
            center_x=cx, center_y=cy,
            angle=wrap_angle(0.5 * math.atan2(float(s[r, col]), float(c[r, col]))),
            width_px=opening, jaw_px=opening * JAW_FRACTION if jaw_px is None else float(jaw_px),
        ))
        if len(out) >= num_grasps:
            break
    return out


def wilson_interval(correct: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (default 95 %); (0, 1) when n = 0.

    Exact at the ends, like the Rust ``lgdm_base::stats::wilson_interval``: no successes give a
    low end of 0, no failures a high end of 1 (the formula's rounding would miss them, e.g.
    0.9999999999999999 for 10/10). Same operations in the same order as the Rust function, so
    both give the values of ``tests/fixtures/wilson.json``."""
    if n <= 0:
        return 0.0, 1.0
    nf = float(n)
    p = min(correct, n) / nf
    z2 = z * z
    denom = 1.0 + z2 / nf
    centre = (p + z2 / (2.0 * nf)) / denom
    half = z * math.sqrt(p * (1.0 - p) / nf + z2 / (4.0 * nf * nf)) / denom
    low = 0.0 if correct <= 0 else max(0.0, centre - half)
    high = 1.0 if correct >= n else min(1.0, centre + half)
    return low, high


def jaw_px_for(jaw_side_fraction: float | None, map_side: int) -> float | None:
    """The ``jaw_px`` to decode with: ``jaw_side_fraction`` (finger width / crop side, from an
    lgdm dataset's index or a checkpoint) times the map side, or None (opening × JAW_FRACTION)."""
    return None if jaw_side_fraction is None else float(jaw_side_fraction) * map_side
