"""A tiny synthetic grasp dataset in the Cornell layout, for tests and smoke runs.

Each object is a box (its own size and colour) lying on a table at random positions and
orientations; the positive grasp closes across the box's short side at its centre, the negative
one tries to close across its long side. Depth is metres from the camera. This is *not* the
project's dataset (``lgdm gen-dataset`` writes that); it only exercises the loader, training and
evaluation end to end. Three layouts:

* ``lgdm`` (default): what ``lgdm gen-dataset`` writes now: square object-centred crops of
  ``CROP_SIZE_PX`` pixels covering ``CROP_SIDE_M`` of table, image k numbered 100 + k in folder
  (100 + k) // 100, object k mod objects, an object-form ``index.json`` (format
  ``lgdm.grasp.v2``) with categories, every positive rectangle's jaw = the finger width;
* ``list``: the older lgdm output: non-square frames, one folder per object, list-form
  ``index.json``, jaw = 0.3 x the box length;
* ``cornell``: like ``list`` without any index (as the real Cornell set).

    python -m train_ae.synthetic --out /tmp/grasp-fixture --objects 4 --images 3
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from PIL import Image

from .data import INDEX_FILE, INDEX_FORMAT
from .grasp import GraspRectangle

TABLE_DEPTH_M = 0.7
"""Distance from the camera to the table plane."""

CROP_SIDE_M = 0.22
CROP_SIZE_PX = 224
FINGER_WIDTH_M = 0.02
CATEGORY_NAMES = ("box", "bar", "slab", "brick", "block", "plank")
LAYOUTS = ("lgdm", "list", "cornell")


def _write_rects(path: Path, rects: list[GraspRectangle]) -> None:
    lines = []
    for r in rects:
        for x, y in r.corners():
            lines.append(f"{x:.2f} {y:.2f}")
    path.write_text("\n".join(lines) + ("\n" if lines else ""))


def _object_name(obj: int, categories: int) -> tuple[int, str, str]:
    cat = obj % categories
    name = CATEGORY_NAMES[cat % len(CATEGORY_NAMES)] + ("" if cat < len(CATEGORY_NAMES)
                                                        else str(cat))
    return cat, name, f"{name}_{obj // categories + 1:02d}"


def write_synthetic_dataset(root: str | Path, objects: int = 4, images_per_object: int = 3,
                            width: int | None = None, height: int | None = None, seed: int = 0,
                            layout: str = "lgdm", categories: int = 2) -> Path:
    """Write the fixture under ``root`` and return ``root``. Sizes default to 224 x 224 for
    ``lgdm`` (which needs a square) and 160 x 128 otherwise."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}: expected one of {LAYOUTS}")
    if categories < 1 or objects < 1 or images_per_object < 1:
        raise ValueError("objects, images per object and categories must be positive")
    lgdm = layout == "lgdm"
    width = width or (CROP_SIZE_PX if lgdm else 160)
    height = height or (CROP_SIZE_PX if lgdm else 128)
    if lgdm and width != height:
        raise ValueError(f"the lgdm layout has square crops, got {width}x{height}")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    side = min(width, height)
    jaw_px = FINGER_WIDTH_M / CROP_SIDE_M * width
    shapes = []
    for _ in range(objects):
        shapes.append((rng.uniform(0.30, 0.45) * side, rng.uniform(0.10, 0.18) * side,
                       rng.uniform(0.03, 0.08), rng.integers(60, 230, size=3)))
    total = objects * images_per_object
    entries = []
    for k in range(total):
        if lgdm:  # as gen-dataset: image k shows object k mod objects, numbered 100 + k
            obj, number = k % objects, 100 + k
            folder = root / f"{number // 100:02d}"
        else:  # one folder per object
            obj, number = k // images_per_object, k
            folder = root / f"{obj + 1:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        long_px, short_px, height_m, colour = shapes[obj]
        phi = rng.uniform(-math.pi / 2, math.pi / 2)  # long axis, counter-clockwise on screen
        if lgdm:  # object-centred crop: the box near the centre
            cx = (width - 1) / 2 + rng.uniform(-0.05, 0.05) * width
            cy = (height - 1) / 2 + rng.uniform(-0.05, 0.05) * height
        else:
            margin = long_px / 2 + 4
            cx = rng.uniform(margin, width - 1 - margin)
            cy = rng.uniform(margin, height - 1 - margin)
        # Box mask: |projection on long axis| <= long/2 and on short axis <= short/2.
        ux, uy = math.cos(phi), -math.sin(phi)
        a = (xs - cx) * ux + (ys - cy) * uy
        b = (xs - cx) * -uy + (ys - cy) * ux
        inside = (np.abs(a) <= long_px / 2) & (np.abs(b) <= short_px / 2)
        depth = np.full((height, width), TABLE_DEPTH_M, np.float32)
        depth += (ys / height * 0.02).astype(np.float32)  # slight table tilt
        depth[inside] = TABLE_DEPTH_M - height_m
        rgb = np.empty((height, width, 3), np.uint8)
        rgb[...] = (200, 190, 170)
        rgb[inside] = colour
        noise = rng.integers(-6, 7, size=rgb.shape)
        rgb = np.clip(rgb.astype(np.int16) + noise, 0, 255).astype(np.uint8)
        jaw = jaw_px if lgdm else long_px * 0.3
        grasp = GraspRectangle(cx, cy, phi + math.pi / 2, short_px + 10, jaw)
        grasp = GraspRectangle.from_corners(grasp.corners())  # wrap the angle
        bad = GraspRectangle.from_corners(
            GraspRectangle(cx, cy, phi, long_px + 10, jaw if lgdm else short_px * 0.5).corners())
        stem = f"pcd{number:04d}"
        Image.fromarray(rgb).save(folder / f"{stem}r.png")
        Image.fromarray(depth).save(folder / f"{stem}d.tiff")
        _write_rects(folder / f"{stem}cpos.txt", [grasp])
        _write_rects(folder / f"{stem}cneg.txt", [bad])
        cat, cat_name, name = _object_name(obj, categories)
        entries.append({"number": number, "prefix": f"{folder.name}/{stem}", "instance": obj,
                        "category": cat, "category_name": cat_name, "object": name,
                        "positives": 1, "negatives": 1})
    if lgdm:
        index = {"format": INDEX_FORMAT,
                 "crop": {"side_m": CROP_SIDE_M, "size_px": width},
                 "finger_width_m": FINGER_WIDTH_M,
                 "jaw_side_fraction": FINGER_WIDTH_M / CROP_SIDE_M,
                 "images": entries}
        (root / INDEX_FILE).write_text(json.dumps(index, indent=1) + "\n")
    elif layout == "list":
        for e in entries:  # the older index had no category names
            del e["category_name"]
        (root / INDEX_FILE).write_text(json.dumps(entries, indent=1) + "\n")
    return root


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.synthetic", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--objects", type=int, default=4)
    p.add_argument("--images", type=int, default=3, help="images per object")
    p.add_argument("--layout", choices=LAYOUTS, default="lgdm")
    p.add_argument("--categories", type=int, default=2, help="lgdm layout: categories")
    p.add_argument("--width", type=int, help="default 224 (lgdm) or 160")
    p.add_argument("--height", type=int, help="default 224 (lgdm) or 128")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    write_synthetic_dataset(a.out, a.objects, a.images, a.width, a.height, a.seed, a.layout,
                            a.categories)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
