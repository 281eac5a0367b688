"""A tiny synthetic grasp dataset in the Cornell layout, for tests and smoke runs.

Each object folder ``<nn>`` holds views of one box (its own size and colour) lying on a table at
random positions and orientations; the positive grasp closes across the box's short side at its
centre, the negative one tries to close across its long side. Depth is metres from the camera.
This is *not* the project's dataset (``lgdm gen-dataset`` writes that); it only exercises the
loader, training and evaluation end to end.

    python -m train_ae.synthetic --out /tmp/grasp-fixture --objects 4 --images 3
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from PIL import Image

from .grasp import GraspRectangle

TABLE_DEPTH_M = 0.7
"""Distance from the camera to the table plane."""


def _write_rects(path: Path, rects: list[GraspRectangle]) -> None:
    lines = []
    for r in rects:
        for x, y in r.corners():
            lines.append(f"{x:.2f} {y:.2f}")
    path.write_text("\n".join(lines) + ("\n" if lines else ""))


def write_synthetic_dataset(root: str | Path, objects: int = 4, images_per_object: int = 3,
                            width: int = 160, height: int = 128, seed: int = 0) -> Path:
    """Write the fixture under ``root`` and return ``root``."""
    root = Path(root)
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    index = 0
    for obj in range(objects):
        folder = root / f"{obj + 1:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        long_px = rng.uniform(0.30, 0.45) * min(width, height)
        short_px = rng.uniform(0.10, 0.18) * min(width, height)
        height_m = rng.uniform(0.03, 0.08)
        colour = rng.integers(60, 230, size=3)
        for _ in range(images_per_object):
            phi = rng.uniform(-math.pi / 2, math.pi / 2)  # long axis, counter-clockwise on screen
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
            grasp = GraspRectangle(cx, cy, phi + math.pi / 2, short_px + 10, long_px * 0.3)
            grasp = GraspRectangle.from_corners(grasp.corners())  # wrap the angle
            bad = GraspRectangle.from_corners(
                GraspRectangle(cx, cy, phi, long_px + 10, short_px * 0.5).corners())
            stem = f"pcd{index:04d}"
            Image.fromarray(rgb).save(folder / f"{stem}r.png")
            Image.fromarray(depth).save(folder / f"{stem}d.tiff")
            _write_rects(folder / f"{stem}cpos.txt", [grasp])
            _write_rects(folder / f"{stem}cneg.txt", [bad])
            index += 1
    return root


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.synthetic", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--objects", type=int, default=4)
    p.add_argument("--images", type=int, default=3, help="images per object")
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    write_synthetic_dataset(a.out, a.objects, a.images, a.width, a.height, a.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
