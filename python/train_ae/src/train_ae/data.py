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

``lgdm gen-dataset`` also writes ``<root>/index.json``. Its current form (``"format":
"lgdm.grasp.v2"``) is an object: ``crop`` (``side_m``, ``size_px``), ``finger_width_m``,
``jaw_side_fraction`` (finger width / crop side: a decoded jaw is this fraction of the map side)
and ``images``, one entry per image with ``prefix`` (``01/pcd0100``), ``object`` (instance name)
and ``category_name`` / ``category``. Every image is then a square, object-centred crop of fixed
metric size. With such an index a sample's object id is its ``object`` and its category the
``category_name``; otherwise (the real Cornell set, or an older list-form index, which is
ignored) the object id is the ``<nn>`` folder and the category unknown. An object map (a text
file of ``<stem> <object id>`` lines, stem like ``pcd0100``) overrides the object ids either
way. Splits hold out whole objects: one instance per category (``split_held_out_instances``)
or a fraction of all objects (``split_by_object``).

Network input (``resize_to_input`` then ``normalize_rgbd``; ``bridge.preprocess`` does the
same): a square image is resized whole to the input size (area averaging for an integer
factor, else bilinear); a non-square (Cornell) image is first cropped to its centred square.
Channel 0 is depth minus its mean (metres; non-finite pixels first set to the mean of the finite
ones), channels 1-3 are RGB scaled to [0, 1] minus their common mean.

Example::

    from train_ae.data import find_samples, split_held_out_instances, GraspDataset

    samples = find_samples("data/grasp")
    train, held_out = split_held_out_instances(samples, per_category=1, seed=0)
    ds = GraspDataset(train, input_size=112, augment=True, seed=0)
    x, targets, rectangles = ds.item(0, epoch=0)   # (4,112,112), (5,112,112), [GraspRectangle]
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

from .grasp import GraspRectangle, grasp_maps, negative_map

ZOOM_RANGE = (0.6, 1.0)
"""Augmentation zoom of non-square (Cornell) images: the crop side is this fraction of the
image's shorter side. Square lgdm crops are never zoomed (their metric scale is fixed)."""

SHIFT_FRACTION = 16 / 224
"""Augmentation of square crops: random integer shift of up to this fraction of the image side
in x and in y (16 px of a 224-px crop), edges replicated."""

INDEX_FILE = "index.json"
INDEX_FORMAT = "lgdm.grasp.v2"
"""``format`` of the object-form ``index.json`` that ``lgdm gen-dataset`` writes."""


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
    category: str | None = None
    """Category name from an lgdm ``index.json``; None when unknown (Cornell, no index)."""
    physics: dict | None = None
    """``lgdm sim grasp-data``'s labels: the scene (``scene``, ``scenario``, ``objects``) and one
    outcome per rectangle, ``positives`` in ``cpos.txt``'s order and ``negatives`` in
    ``cneg.txt``'s (each ``source``, ``rank``, ``success``, ``reason``, ``reaches_contacts``).
    None for geometric labels (``gen-dataset``, Cornell)."""

    @property
    def stem(self) -> str:
        return self.rgb_path.name[: -len("r.png")]


@dataclass
class Rectangles:
    positives: list[GraspRectangle]
    negatives: list[GraspRectangle] = field(default_factory=list)
    skipped_nan: int = 0


_STEM = re.compile(r"^(pcd\d+)r\.png$")


@dataclass(frozen=True)
class GraspIndex:
    """The object-form ``index.json`` of an lgdm grasp dataset (``format`` lgdm.grasp.v2)."""

    path: Path
    jaw_side_fraction: float | None
    """Jaw length of a decoded grasp as a fraction of the image (or map) side; the finger
    width over the crop side."""
    crop_side_m: float | None
    crop_size_px: int | None
    finger_width_m: float | None
    images: dict[str, dict]
    """Entries by ``prefix`` (``01/pcd0100``)."""


def _positive_number(path: Path, key: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise DatasetError(f"{path}: {key} must be a positive number, got {v!r}")
    return float(v)


def read_grasp_index(root: str | Path) -> GraspIndex | None:
    """``<root>/index.json`` in its object form, or None when there is no index or it is the
    older list form (which carries no crop or jaw information and is not used)."""
    path = Path(root) / INDEX_FILE
    if not path.is_file():
        return None
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DatasetError(f"{path}: not readable JSON: {e}") from e
    if isinstance(raw, list):
        return None
    if not isinstance(raw, dict):
        raise DatasetError(f"{path}: expected a JSON object or list, got {type(raw).__name__}")
    if raw.get("format") != INDEX_FORMAT:
        raise DatasetError(f"{path}: format is {raw.get('format')!r}, expected {INDEX_FORMAT!r}")
    crop = raw.get("crop") or {}
    if not isinstance(crop, dict):
        raise DatasetError(f"{path}: crop must be an object, got {crop!r}")
    side_m = crop.get("side_m")
    side_m = None if side_m is None else _positive_number(path, "crop.side_m", side_m)
    size_px = crop.get("size_px")
    if size_px is not None and (isinstance(size_px, bool) or not isinstance(size_px, int)
                                or size_px < 1):
        raise DatasetError(f"{path}: crop.size_px must be a positive integer, got {size_px!r}")
    finger = raw.get("finger_width_m")
    finger = None if finger is None else _positive_number(path, "finger_width_m", finger)
    jaw = raw.get("jaw_side_fraction")
    if jaw is not None:
        jaw = _positive_number(path, "jaw_side_fraction", jaw)
    elif finger is not None and side_m is not None:
        jaw = finger / side_m
    if jaw is not None and jaw >= 1:
        raise DatasetError(f"{path}: jaw_side_fraction must be below 1, got {jaw!r}")
    entries = raw.get("images")
    if not isinstance(entries, list):
        raise DatasetError(f"{path}: 'images' must be a list of entries")
    images: dict[str, dict] = {}
    for i, e in enumerate(entries):
        if not isinstance(e, dict) or not isinstance(e.get("prefix"), str):
            raise DatasetError(f"{path}: images[{i}] has no string 'prefix'")
        obj = e.get("object")
        if not isinstance(obj, str) or not obj or any(c.isspace() for c in obj):
            raise DatasetError(f"{path}: images[{i}] ({e['prefix']}): 'object' must be a "
                               f"non-empty name without spaces, got {obj!r}")
        if e["prefix"] in images:
            raise DatasetError(f"{path}: images[{i}]: prefix {e['prefix']!r} appears twice")
        _check_physics(path, i, e)
        images[e["prefix"]] = e
    return GraspIndex(path, jaw, side_m, size_px, finger, images)


def _check_physics(path: Path, i: int, entry: dict) -> None:
    """An entry's ``physics`` block, when there is one: an outcome per rectangle, successes for
    the positives and failures for the negatives."""
    physics = entry.get("physics")
    if physics is None:
        return
    where = f"{path}: images[{i}] ({entry['prefix']}): physics"
    if not isinstance(physics, dict):
        raise DatasetError(f"{where} must be an object")
    for key, held in (("positives", True), ("negatives", False)):
        outcomes = physics.get(key)
        if not isinstance(outcomes, list):
            raise DatasetError(f"{where}.{key} must be a list of outcomes")
        count = entry.get(key)
        if count is not None and len(outcomes) != count:
            raise DatasetError(f"{where}.{key} has {len(outcomes)} outcomes for {count} "
                               f"rectangles")
        for k, o in enumerate(outcomes):
            if not isinstance(o, dict) or o.get("success") is not held:
                raise DatasetError(f"{where}.{key}[{k}]: success must be {held}, got {o!r}")


def _entry_category(entry: dict) -> str | None:
    name = entry.get("category_name")
    if name is not None:
        return str(name)
    cat = entry.get("category")
    return None if cat is None else str(cat)


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
    """All samples under ``root``, sorted by folder then file name.

    Object ids and categories come from an lgdm ``index.json`` (object form) when there is one,
    else object = folder and no category; ``object_map`` overrides the object ids. With an
    index, every image must have an entry and every entry an image.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"dataset directory {root} does not exist")
    index = read_grasp_index(root)
    seen: set[str] = set()
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
            obj, category, physics = folder.name, None, None
            if index is not None:
                prefix = f"{folder.name}/{stem}"
                entry = index.images.get(prefix)
                if entry is None:
                    raise DatasetError(f"{index.path} has no entry for {prefix} ({rgb})")
                seen.add(prefix)
                obj, category = entry["object"], _entry_category(entry)
                physics = entry.get("physics")
            if object_map is not None:
                if stem not in object_map:
                    raise DatasetError(f"object map has no entry for {stem} ({rgb})")
                obj = object_map[stem]
            samples.append(Sample(obj, rgb, depth, cpos, cneg if cneg.is_file() else None,
                                  category, physics))
    if not samples:
        raise DatasetError(f"no pcdNNNNr.png images found in the sub-folders of {root}")
    if index is not None and len(seen) != len(index.images):
        missing = sorted(set(index.images) - seen)
        raise DatasetError(f"{index.path} lists {len(missing)} image(s) not found under {root}, "
                           f"e.g. {root / missing[0]}r.png")
    return samples


def find_samples_in(roots: list[Path], object_map: dict[str, str] | None = None
                    ) -> tuple[list[Sample], float | None]:
    """(samples, jaw_side_fraction) of several dataset directories, in the order given.

    An object keeps its name across directories, so a name held out is held out of every
    directory (``gen-dataset`` and ``lgdm sim grasp-data`` of one generator seed name the same
    object alike; of another seed, a same-named object is a different one, held out with it).
    The directories must agree on the jaw (``index.json``'s ``jaw_side_fraction``): decoded
    grasps and rectangles would otherwise mean different widths.
    """
    if not roots:
        raise DatasetError("no dataset directory given")
    if len(set(roots)) != len(roots):
        raise DatasetError(f"a dataset directory is given twice: {[str(r) for r in roots]}")
    samples: list[Sample] = []
    jaw: tuple[Path, float | None] | None = None
    for root in roots:
        samples.extend(find_samples(root, object_map))
        index = read_grasp_index(root)
        this = index.jaw_side_fraction if index is not None else None
        if jaw is None:
            jaw = (root, this)
        elif (this is None) != (jaw[1] is None) or (
                this is not None and abs(this - jaw[1]) > 1e-6 * this):
            raise DatasetError(f"{root} decodes jaws with jaw_side_fraction {this}, {jaw[0]} "
                               f"with {jaw[1]}: the directories were made for different "
                               f"fingers or crops")
    return samples, jaw[1]


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


def split_held_out_instances(samples: list[Sample], per_category: int = 1, seed: int = 0
                             ) -> tuple[list[Sample], list[Sample]]:
    """(train, held-out): for each category (in sorted order), a seeded choice of
    ``per_category`` whole objects held out.

    A category keeps at least one object for training: one with k objects holds out
    min(per_category, k - 1). Every sample needs a category (an lgdm ``index.json``); sample
    order is preserved within each part.
    """
    if per_category < 0:
        raise ValueError(f"per_category must be non-negative, got {per_category}")
    unknown = [s for s in samples if s.category is None]
    if unknown:
        raise ValueError(f"{unknown[0].rgb_path} has no category (no lgdm index.json): hold "
                         f"out a fraction of objects instead")
    by_cat: dict[str, set[str]] = {}
    for s in samples:
        by_cat.setdefault(s.category, set()).add(s.object_id)
    rng = np.random.default_rng(seed)
    held: set[str] = set()
    for cat in sorted(by_cat):
        objects = sorted(by_cat[cat])
        k = min(per_category, len(objects) - 1)
        if k > 0:
            held.update(rng.permutation(objects)[:k].tolist())
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
    """(C, S, S) float32 -> (C, size, size): the identity at the same size, area averaging when
    S is an integer multiple of ``size``, else bilinear with half-pixel alignment (pixel
    centres at integer coordinates on both sides)."""
    _, h, w = img.shape
    if h != w:
        raise ValueError(f"resize expects a square image, got {h}x{w}")
    if h == size:
        return img
    t = torch.from_numpy(np.ascontiguousarray(img, dtype=np.float32))[None]
    if h % size == 0:
        k = h // size
        out = F.avg_pool2d(t, kernel_size=k, stride=k)
    else:
        out = F.interpolate(t, size=(size, size), mode="bilinear", align_corners=False)
    return out[0].numpy()


def resize_to_input(rgb: np.ndarray, depth: np.ndarray, size: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """A square image resized whole to ``size`` x ``size``: (rgb float32 (size, size, 3) in
    0-255, depth float32 (size, size) metres, non-finite pixels first set to the mean of the
    finite ones). Area averaging for an integer factor (224 -> 112), else bilinear, half-pixel
    aligned. The one resize of training, evaluation and ``bridge.preprocess``; give the result
    to ``normalize_rgbd``."""
    rgb = np.asarray(rgb)
    depth = np.asarray(depth, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be (H, W, 3), got {rgb.shape}")
    if depth.shape != rgb.shape[:2]:
        raise ValueError(f"depth must be (H, W) = {rgb.shape[:2]}, got {depth.shape}")
    if rgb.shape[0] != rgb.shape[1]:
        raise ValueError(f"resize_to_input needs a square image, got {rgb.shape[0]}x"
                         f"{rgb.shape[1]}")
    if size < 1:
        raise ValueError(f"size must be positive, got {size}")
    stack = np.concatenate([_fill_nonfinite(depth)[None],
                            rgb.astype(np.float32).transpose(2, 0, 1)])
    out = _resize(stack, int(size))
    return np.ascontiguousarray(out[1:].transpose(1, 2, 0)), np.ascontiguousarray(out[0])


def _shift_edge(img: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """(C, H, W) content moved by (dx, dy) pixels (x right, y down), edges replicated."""
    if not dx and not dy:
        return img
    _, h, w = img.shape
    px, py = abs(dx), abs(dy)
    padded = np.pad(img, ((0, 0), (py, py), (px, px)), mode="edge")
    return padded[:, py - dy:py - dy + h, px - dx:px - dx + w]


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

    Square images (lgdm's object-centred crops of fixed metric size) are resized whole to
    ``input_size`` (``resize_to_input``). Training augmentation: an integer shift of up to
    ``SHIFT_FRACTION`` of the side in x and y (edges replicated), a horizontal flip with
    probability 1/2 and a random multiple of 90° rotation; never a zoom.

    Non-square (Cornell) images: without augmentation (evaluation) each image is cropped to the
    centred square of its shorter side and resized: the labels never frame a test input. With
    augmentation the square is centred on the mean centre of the positive rectangles (kept
    inside the image), its side scaled by a zoom drawn from ``ZOOM_RANGE``, and the result
    rotated by a random multiple of 90°.

    Rectangles go through the same transform as the image. The random draw depends only on
    (seed, epoch, index), so results do not depend on batch order.
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
        """(input (4, S, S), targets (5, S, S), positive rectangles): the targets are quality,
        cos 2θ, sin 2θ, width (``grasp_maps`` of the positives) and the negative mask
        (``negative_map`` of the negatives)."""
        sample = self.samples[index]
        rgb, depth = load_images(sample)
        labels = load_rectangles(sample)
        rects = (labels.positives, labels.negatives)
        if not self.augment:
            return self._render(rgb, depth, rects)
        rng = np.random.default_rng([self.seed, epoch, index])
        h, w = depth.shape
        if h == w:
            rot = int(rng.integers(0, 4))
            flip = bool(rng.integers(0, 2))
            m = round(SHIFT_FRACTION * h)
            dx, dy = (int(v) for v in rng.integers(-m, m + 1, size=2))
            return self._render(rgb, depth, rects, rot90=rot, flip=flip, shift=(dx, dy))
        zoom = float(rng.uniform(*ZOOM_RANGE))
        rot = int(rng.integers(0, 4))
        return self._render(rgb, depth, rects, zoom, rot, center_on_grasps=True)

    def render(self, index: int, zoom: float = 1.0, rot90: int = 0,
               center_on_grasps: bool = False, flip: bool = False,
               shift: tuple[int, int] = (0, 0)
               ) -> tuple[np.ndarray, np.ndarray, list[GraspRectangle]]:
        """``item`` with explicit transforms: number of counter-clockwise quarter turns; for
        square images a horizontal flip and an integer (dx, dy) shift in image pixels (applied
        first: shift, flip, rotation); for non-square images a zoom (crop side / shorter image
        side, in (0, 1]) and the crop centre (grasps' or image's)."""
        sample = self.samples[index]
        rgb, depth = load_images(sample)
        labels = load_rectangles(sample)
        return self._render(rgb, depth, (labels.positives, labels.negatives), zoom, rot90,
                            center_on_grasps, flip, shift)

    def _render(self, rgb: np.ndarray, depth: np.ndarray,
                rects: tuple[list[GraspRectangle], list[GraspRectangle]],
                zoom: float = 1.0, rot90: int = 0, center_on_grasps: bool = False,
                flip: bool = False, shift: tuple[int, int] = (0, 0)
                ) -> tuple[np.ndarray, np.ndarray, list[GraspRectangle]]:
        rot = rot90 % 4
        h, w = depth.shape
        if h == w:
            if zoom != 1.0:
                raise ValueError("square crops have a fixed scale: zoom must be 1")
            return self._render_square(rgb, depth, rects, rot, flip, shift)
        if flip or tuple(shift) != (0, 0):
            raise ValueError("flip and shift apply to square crops only")
        if not 0 < zoom <= 1:
            raise ValueError(f"zoom must be in (0, 1], got {zoom}")
        side = min(h, w) * zoom
        positives, negatives = rects
        if positives and center_on_grasps:
            cx = float(np.mean([r.center_x for r in positives]))
            cy = float(np.mean([r.center_y for r in positives]))
        else:
            cx, cy = (w - 1) / 2, (h - 1) / 2
        x0 = round(min(max(cx + 0.5 - side / 2, 0.0), w - side))
        y0 = round(min(max(cy + 0.5 - side / 2, 0.0), h - side))
        side_i = max(round(side), 1)
        side_i = min(side_i, w - x0, h - y0)
        s = self.input_size
        crop_rgb, crop_d = resize_to_input(rgb[y0:y0 + side_i, x0:x0 + side_i],
                                           depth[y0:y0 + side_i, x0:x0 + side_i], s)
        if rot:
            crop_rgb = np.rot90(crop_rgb, rot, axes=(0, 1))
            crop_d = np.rot90(crop_d, rot, axes=(0, 1))
        x = normalize_rgbd(crop_rgb, crop_d)
        out_rects = [_transform_rect(r, x0, y0, side_i, s, rot) for r in positives]
        out_neg = [_transform_rect(r, x0, y0, side_i, s, rot) for r in negatives]
        return x, _targets(out_rects, out_neg, s), out_rects

    def _render_square(self, rgb: np.ndarray, depth: np.ndarray,
                       rects: tuple[list[GraspRectangle], list[GraspRectangle]],
                       rot: int, flip: bool, shift: tuple[int, int]
                       ) -> tuple[np.ndarray, np.ndarray, list[GraspRectangle]]:
        n = depth.shape[0]
        dx, dy = (int(v) for v in shift)
        if rot or flip or dx or dy:
            img = np.concatenate([depth[None].astype(np.float32),
                                  rgb.astype(np.float32).transpose(2, 0, 1)])
            img = _shift_edge(img, dx, dy)
            if flip:
                img = img[:, :, ::-1]
            if rot:
                img = np.rot90(img, rot, axes=(1, 2))
            rgb, depth = img[1:].transpose(1, 2, 0), img[0]
        s = self.input_size
        rgb_s, depth_s = resize_to_input(rgb, depth, s)
        x = normalize_rgbd(rgb_s, depth_s)
        def move(r: GraspRectangle) -> GraspRectangle:
            pts = r.corners() + np.array([dx, dy], dtype=np.float64)
            if flip:  # x -> n - 1 - x mirrors the angle; corner order keeps its meaning
                pts = np.stack([n - 1 - pts[:, 0], pts[:, 1]], axis=1)
            for _ in range(rot):  # np.rot90 (counter-clockwise): (x, y) -> (y, n - 1 - x)
                pts = np.stack([pts[:, 1], n - 1 - pts[:, 0]], axis=1)
            return GraspRectangle.from_corners((pts + 0.5) * (s / n) - 0.5)

        out_rects = [move(r) for r in rects[0]]
        return x, _targets(out_rects, [move(r) for r in rects[1]], s), out_rects

    def batch(self, indices: list[int], epoch: int = 0
              ) -> tuple[torch.Tensor, torch.Tensor, list[list[GraspRectangle]]]:
        items = [self.item(i, epoch) for i in indices]
        x = torch.from_numpy(np.stack([it[0] for it in items]))
        y = torch.from_numpy(np.stack([it[1] for it in items]))
        return x, y, [it[2] for it in items]


def _targets(positives: list[GraspRectangle], negatives: list[GraspRectangle], s: int
             ) -> np.ndarray:
    """(5, s, s): ``grasp_maps`` of the positives, then ``negative_map`` of the negatives."""
    maps = grasp_maps(positives, (s, s))
    return np.stack([*maps, negative_map(negatives, maps[0])])
