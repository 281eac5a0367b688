"""Cornell-layout grasp datasets: loading, object-wise splits, augmentation, normalisation.

Layout (what ``lgdm gen-dataset`` writes, and the Cornell grasping dataset after its point clouds
are turned into depth images)::

    <root>/<nn>/pcdNNNNr.png       RGB, 8 bit
    <root>/<nn>/pcdNNNNd.tiff      depth, single-channel float32, metres
    <root>/<nn>/pcdNNNNcpos.txt    positive grasp rectangles: four "x y" lines each
    <root>/<nn>/pcdNNNNcneg.txt    negative (rejected) rectangles, same format; optional

The real Cornell set ships ``pcdNNNN.txt`` point clouds instead of ``d.tiff``; convert them first
(e.g. GG-CNN's ``generate_cornell_depth.py`` writes exactly ``pcdNNNNd.tiff``). Rectangles with a
NaN coordinate (a few real Cornell files have them) are skipped and counted; any other malformed
rectangle file is an error naming the file and line.

A sample's object id is its ``<nn>`` folder unless an object map is given (a text file of
``<stem> <object id>`` lines, stem like ``pcd0100``); splits hold out whole objects.

Network input: channel 0 is depth minus its mean (metres; non-finite pixels first set to the
mean of the finite ones), channels 1-3 are RGB scaled to [0, 1] minus their common mean.

Example::

    from train_ae.data import find_samples, split_by_object, GraspDataset

    samples = find_samples("data/grasp")
    train, held_out = split_by_object(samples, held_out_fraction=0.1, seed=0)
    ds = GraspDataset(train, input_size=112, augment=True, seed=0)
    x, targets, rectangles = ds.item(0, epoch=0)   # (4,112,112), (4,112,112), [GraspRectangle]
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

from .grasp import GraspRectangle, grasp_maps

ZOOM_RANGE = (0.6, 1.0)
"""Augmentation zoom: the crop side is this fraction of the image's shorter side."""


class DatasetError(ValueError):
    """A dataset file or directory is missing or malformed; the message names it."""


@dataclass(frozen=True)
class Sample:
    """One grasp-labelled image on disk."""

    object_id: str
    rgb_path: Path
    depth_path: Path
    cpos_path: Path
    cneg_path: Path | None = None

    @property
    def stem(self) -> str:
        return self.rgb_path.name[: -len("r.png")]


@dataclass
class Rectangles:
    positives: list[GraspRectangle]
    negatives: list[GraspRectangle] = field(default_factory=list)
    skipped_nan: int = 0


_STEM = re.compile(r"^(pcd\d+)r\.png$")


def read_object_map(path: str | Path) -> dict[str, str]:
    """``<stem> <object id>`` per line ('#' comments and blank lines allowed)."""
    path = Path(path)
    out: dict[str, str] = {}
    for i, line in enumerate(path.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) != 2:
            raise DatasetError(f"{path}:{i}: expected '<stem> <object id>', got {line!r}")
        out[parts[0]] = parts[1]
    return out


def find_samples(root: str | Path, object_map: dict[str, str] | None = None) -> list[Sample]:
    """All samples under ``root``, sorted by folder then file name."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"dataset directory {root} does not exist")
    samples: list[Sample] = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        for rgb in sorted(folder.iterdir()):
            m = _STEM.match(rgb.name)
            if not m:
                continue
            stem = m.group(1)
            depth = folder / f"{stem}d.tiff"
            cpos = folder / f"{stem}cpos.txt"
            cneg = folder / f"{stem}cneg.txt"
            if not depth.is_file():
                hint = ""
                if (folder / f"{stem}.txt").is_file():
                    hint = (" (this looks like the original Cornell layout with point clouds; "
                            "convert them to pcdNNNNd.tiff depth images first)")
                raise DatasetError(f"{depth} is missing for {rgb}{hint}")
            if not cpos.is_file():
                raise DatasetError(f"{cpos} is missing for {rgb}")
            if object_map is not None:
                if stem not in object_map:
                    raise DatasetError(f"object map has no entry for {stem} ({rgb})")
                obj = object_map[stem]
            else:
                obj = folder.name
            samples.append(Sample(obj, rgb, depth, cpos, cneg if cneg.is_file() else None))
    if not samples:
        raise DatasetError(f"no pcdNNNNr.png images found in the sub-folders of {root}")
    return samples


def read_rectangles(path: str | Path) -> tuple[list[GraspRectangle], int]:
    """Rectangles of a Cornell ``cpos``/``cneg`` file and the number skipped for NaNs."""
    path = Path(path)
    points: list[tuple[float, float]] = []
    lines: list[int] = []
    for i, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        parts = line.split()
        if len(parts) != 2:
            raise DatasetError(f"{path}:{i}: expected two numbers 'x y', got {line.strip()!r}")
        try:
            x, y = float(parts[0]), float(parts[1])
        except ValueError:
            raise DatasetError(f"{path}:{i}: not a number in {line.strip()!r}") from None
        if math.isinf(x) or math.isinf(y):
            raise DatasetError(f"{path}:{i}: infinite coordinate in {line.strip()!r}")
        points.append((x, y))
        lines.append(i)
    if len(points) % 4:
        raise DatasetError(f"{path}: {len(points)} corner lines is not a multiple of 4 "
                           f"(four 'x y' lines per rectangle)")
    rects: list[GraspRectangle] = []
    skipped = 0
    for k in range(0, len(points), 4):
        corners = np.array(points[k:k + 4])
        if np.isnan(corners).any():
            skipped += 1
            continue
        r = GraspRectangle.from_corners(corners)
        if r.width_px <= 0 or r.jaw_px <= 0:
            raise DatasetError(f"{path}:{lines[k]}: degenerate rectangle (zero-length edge)")
        rects.append(r)
    return rects, skipped


def load_rectangles(sample: Sample) -> Rectangles:
    pos, skipped = read_rectangles(sample.cpos_path)
    neg: list[GraspRectangle] = []
    if sample.cneg_path is not None:
        neg, s2 = read_rectangles(sample.cneg_path)
        skipped += s2
    return Rectangles(pos, neg, skipped)


def load_images(sample: Sample) -> tuple[np.ndarray, np.ndarray]:
    """(rgb uint8 (H, W, 3), depth float32 (H, W) metres)."""
    try:
        with Image.open(sample.rgb_path) as im:
            rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (OSError, ValueError) as e:
        raise DatasetError(f"{sample.rgb_path}: cannot read RGB image: {e}") from e
    try:
        with Image.open(sample.depth_path) as im:
            depth = np.asarray(im, dtype=np.float32)
    except (OSError, ValueError) as e:
        raise DatasetError(f"{sample.depth_path}: cannot read depth image: {e}") from e
    if depth.ndim != 2:
        raise DatasetError(f"{sample.depth_path}: depth must be single-channel, got shape "
                           f"{depth.shape}")
    if depth.shape != rgb.shape[:2]:
        raise DatasetError(f"{sample.depth_path}: depth {depth.shape} and RGB {rgb.shape[:2]} "
                           f"sizes differ")
    return rgb, depth


def split_by_object(samples: list[Sample], held_out_fraction: float, seed: int
                    ) -> tuple[list[Sample], list[Sample]]:
    """(train, held-out): a seeded choice of ceil(fraction * objects) whole objects held out.

    With a positive fraction and at least two objects, at least one object is held out and at
    least one is kept for training. Sample order is preserved within each part.
    """
    if not 0.0 <= held_out_fraction < 1.0:
        raise ValueError(f"held-out fraction must be in [0, 1), got {held_out_fraction}")
    objects = sorted({s.object_id for s in samples})
    n_out = math.ceil(held_out_fraction * len(objects)) if held_out_fraction > 0 else 0
    if n_out and len(objects) >= 2:
        n_out = min(n_out, len(objects) - 1)
    elif len(objects) < 2:
        n_out = 0
    rng = np.random.default_rng(seed)
    held = set(rng.permutation(objects)[:n_out].tolist())
    train = [s for s in samples if s.object_id not in held]
    out = [s for s in samples if s.object_id in held]
    return train, out


# --- geometry of crop, resize, rotation ----------------------------------------------------------

def _transform_rect(r: GraspRectangle, x0: float, y0: float, side: float, size: int,
                    rot90: int) -> GraspRectangle:
    """Crop origin (x0, y0) and side, resize to ``size`` (pixel-centre aligned), rotate k*90°."""
    s = size / side
    pts = (r.corners() - np.array([x0, y0]) + 0.5) * s - 0.5
    for _ in range(rot90 % 4):  # np.rot90 (counter-clockwise): (x, y) -> (y, size - 1 - x)
        pts = np.stack([pts[:, 1], size - 1 - pts[:, 0]], axis=1)
    return GraspRectangle.from_corners(pts)


def _resize(img: np.ndarray, size: int) -> np.ndarray:
    """Bilinear resize of (C, H, W) float32 to (C, size, size), half-pixel aligned."""
    if img.shape[1:] == (size, size):
        return img
    t = torch.from_numpy(np.ascontiguousarray(img))[None]
    return F.interpolate(t, size=(size, size), mode="bilinear", align_corners=False)[0].numpy()


def normalize_rgbd(rgb: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """The training normalisation: (4, H, W) float32 [depth - mean, RGB/255 - mean].

    ``rgb`` is (H, W, 3) (uint8 0-255, or float already in 0-255) and ``depth`` (H, W) metres.
    """
    rgb = np.asarray(rgb)
    depth = np.asarray(depth, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be (H, W, 3), got {rgb.shape}")
    if depth.shape != rgb.shape[:2]:
        raise ValueError(f"depth must be (H, W) = {rgb.shape[:2]}, got {depth.shape}")
    d = _fill_nonfinite(depth)
    d = d - d.mean(dtype=np.float64).astype(np.float32)
    c = rgb.astype(np.float32) / np.float32(255.0)
    c = c - c.mean(dtype=np.float64).astype(np.float32)
    return np.concatenate([d[None], c.transpose(2, 0, 1)], axis=0).astype(np.float32)


def _fill_nonfinite(depth: np.ndarray) -> np.ndarray:
    ok = np.isfinite(depth)
    if ok.all():
        return depth
    fill = np.float32(depth[ok].mean()) if ok.any() else np.float32(0.0)
    return np.where(ok, depth, fill).astype(np.float32)


class GraspDataset:
    """Samples turned into network inputs and targets, with seeded augmentation.

    Without augmentation (evaluation) each image is cropped to the centred square of its shorter
    side and resized to ``input_size``: the labels never frame a test input. With augmentation
    (training) the square is centred on the mean centre of the positive rectangles (kept inside
    the image), its side scaled by a zoom drawn from ``ZOOM_RANGE``, and the result rotated by a
    random multiple of 90°. Rectangles go through the same transform as the image. The random
    draw depends only on (seed, epoch, index), so results do not depend on batch order.
    """

    def __init__(self, samples: list[Sample], input_size: int, augment: bool, seed: int = 0):
        self.samples = list(samples)
        self.input_size = int(input_size)
        self.augment = augment
        self.seed = int(seed)

    def __len__(self) -> int:
        return len(self.samples)

    def item(self, index: int, epoch: int = 0
             ) -> tuple[np.ndarray, np.ndarray, list[GraspRectangle]]:
        """(input (4, S, S), targets (4, S, S) = quality, cos2θ, sin2θ, width, rectangles)."""
        zoom, rot = 1.0, 0
        if self.augment:
            rng = np.random.default_rng([self.seed, epoch, index])
            zoom = float(rng.uniform(*ZOOM_RANGE))
            rot = int(rng.integers(0, 4))
        return self.render(index, zoom, rot, center_on_grasps=self.augment)

    def render(self, index: int, zoom: float = 1.0, rot90: int = 0,
               center_on_grasps: bool = False
               ) -> tuple[np.ndarray, np.ndarray, list[GraspRectangle]]:
        """``item`` with an explicit zoom (crop side / shorter image side, in (0, 1]), number
        of counter-clockwise quarter turns and crop centre (grasps' or image's)."""
        if not 0 < zoom <= 1:
            raise ValueError(f"zoom must be in (0, 1], got {zoom}")
        rot = rot90 % 4
        sample = self.samples[index]
        rgb, depth = load_images(sample)
        rects = load_rectangles(sample).positives
        h, w = depth.shape
        side = min(h, w) * zoom
        if rects and center_on_grasps:
            cx = float(np.mean([r.center_x for r in rects]))
            cy = float(np.mean([r.center_y for r in rects]))
        else:
            cx, cy = (w - 1) / 2, (h - 1) / 2
        x0 = round(min(max(cx + 0.5 - side / 2, 0.0), w - side))
        y0 = round(min(max(cy + 0.5 - side / 2, 0.0), h - side))
        side_i = max(round(side), 1)
        side_i = min(side_i, w - x0, h - y0)
        crop_rgb = rgb[y0:y0 + side_i, x0:x0 + side_i].astype(np.float32).transpose(2, 0, 1)
        crop_d = _fill_nonfinite(depth[y0:y0 + side_i, x0:x0 + side_i])[None]
        s = self.input_size
        img = _resize(np.concatenate([crop_d, crop_rgb]), s)
        if rot:
            img = np.rot90(img, rot, axes=(1, 2))
        x = normalize_rgbd(img[1:].transpose(1, 2, 0), img[0])
        out_rects = [_transform_rect(r, x0, y0, side_i, s, rot) for r in rects]
        targets = np.stack(grasp_maps(out_rects, (s, s)))
        return x, targets, out_rects

    def batch(self, indices: list[int], epoch: int = 0
              ) -> tuple[torch.Tensor, torch.Tensor, list[list[GraspRectangle]]]:
        items = [self.item(i, epoch) for i in indices]
        x = torch.from_numpy(np.stack([it[0] for it in items]))
        y = torch.from_numpy(np.stack([it[1] for it in items]))
        return x, y, [it[2] for it in items]
