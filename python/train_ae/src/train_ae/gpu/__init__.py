"""Training on a GPU from packs (``train_ae.pack``): the images and their label maps held on
the device, augmented there, large batches under bf16 autocast, a wall-clock budget.

The command is ``python -m train_ae.gpu`` (``__main__.py``); this module is its library.

Same data as ``train_ae.train`` sees, by construction:

* **Augmentation** — ``data.GraspDataset``'s for square crops: an integer shift of up to
  ``data.SHIFT_FRACTION`` of the side (edges replicated), a horizontal flip, a number of
  quarter turns, applied in that order; then training's resize (area averaging by an integer
  factor) and ``data.normalize_rgbd``'s normalisation (non-finite depth first set to the mean
  of the finite pixels). Here a gather of pixel indices per image; the draws come from
  ``numpy.random.default_rng([seed, epoch])`` per epoch (same distributions, other numbers).
* **Targets** — ``grasp.grasp_maps`` and ``grasp.negative_map`` themselves, computed once per
  image on a canvas padded by the largest shift (``label_canvases``; one canvas per sub-pixel
  offset when the input is an integer factor smaller than the crop) and then moved exactly as
  the image is: pixels whose centres lie inside a rectangle stay inside under integer shifts,
  flips and quarter turns, which turn cos 2θ and sin 2θ by a sign. ``tests/test_gpu.py`` checks
  inputs and targets against ``GraspDataset.render`` of the directory, transform by transform.
* **Loss** — ``training.grasp_loss``; evaluation — ``training.evaluate_model`` on
  ``pack.PackedGraspDataset`` (the directory loader's ``_render`` on the pack's arrays).
"""

from __future__ import annotations

import math
import mmap
import multiprocessing
import os
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from ..data import SHIFT_FRACTION
from ..grasp import GraspRectangle, grasp_maps, negative_map
from ..model import GraspMaps
from ..pack import Pack


@dataclass(frozen=True)
class CanvasGeometry:
    """Label canvases of an ``n``-px crop for a ``size``-px input."""

    n: int
    size: int

    @property
    def factor(self) -> int:
        """Crop pixels per input pixel (1 or an integer)."""
        return self.n // self.size

    @property
    def shift(self) -> int:
        """Largest augmentation shift in crop pixels (``GraspDataset``'s)."""
        return round(SHIFT_FRACTION * self.n)

    @property
    def pad(self) -> int:
        """Canvas margin in input pixels."""
        return math.ceil(self.shift / self.factor)

    @property
    def side(self) -> int:
        return self.size + 2 * self.pad

    @property
    def offsets(self) -> int:
        """Canvases per image: one per sub-pixel offset (rx, ry), index ry * factor + rx."""
        return self.factor * self.factor

    def check(self) -> None:
        if self.size > self.n or self.n % self.size:
            raise ValueError(f"input size {self.size} must divide the pack's crop side {self.n} "
                             f"(e.g. 224 -> 224 or 112)")


def canvas_maps(positives: list[GraspRectangle], negatives: list[GraspRectangle],
                geom: CanvasGeometry, rx: int, ry: int) -> np.ndarray:
    """(5, side, side) float32: ``grasp_maps`` + ``negative_map`` of the rectangles resized to
    the input (``GraspDataset``'s pixel-centre alignment), moved by (rx, ry) / factor of an
    input pixel and by the margin."""
    off = np.array([rx / geom.factor + geom.pad, ry / geom.factor + geom.pad])
    scale = geom.size / geom.n

    def move(r: GraspRectangle) -> GraspRectangle:
        return GraspRectangle.from_corners((r.corners() + 0.5) * scale - 0.5 + off)

    shape = (geom.side, geom.side)
    maps = grasp_maps([move(r) for r in positives], shape)
    return np.stack([*maps, negative_map([move(r) for r in negatives], maps[0])])


_JOB: dict = {}
"""What forked workers of ``label_canvases`` read: the shared output and the rectangles."""


def _fill(span: tuple[int, int]) -> int:
    out, positives, negatives, geom = (_JOB[k] for k in ("out", "pos", "neg", "geom"))
    for i in range(*span):
        for ry in range(geom.factor):
            for rx in range(geom.factor):
                out[i, ry * geom.factor + rx] = canvas_maps(positives[i], negatives[i], geom,
                                                            rx, ry)
    return span[1] - span[0]


def label_canvases(positives: list[list[GraspRectangle]], negatives: list[list[GraspRectangle]],
                   geom: CanvasGeometry, workers: int = 1) -> np.ndarray:
    """(N, offsets, 5, side, side) float32 canvases of every image; ``workers`` > 1 forks
    processes that write into one shared buffer (call before CUDA is initialised)."""
    geom.check()
    n = len(positives)
    shape = (n, geom.offsets, 5, geom.side, geom.side)
    nbytes = int(np.prod(shape)) * 4
    spans = [(i, min(i + 64, n)) for i in range(0, n, 64)]
    if workers > 1 and n > 64 and "fork" in multiprocessing.get_all_start_methods():
        buf = mmap.mmap(-1, max(nbytes, 1))  # MAP_SHARED: the children's writes are ours
        out = np.frombuffer(buf, np.float32, count=int(np.prod(shape))).reshape(shape)
        _JOB.update(out=out, pos=positives, neg=negatives, geom=geom)
        try:
            with multiprocessing.get_context("fork").Pool(min(workers, len(spans))) as pool:
                done = sum(pool.imap_unordered(_fill, spans))
        finally:
            _JOB.clear()
        if done != n:
            raise RuntimeError(f"label canvases: {done} of {n} images filled")
        return out
    out = np.empty(shape, np.float32)
    _JOB.update(out=out, pos=positives, neg=negatives, geom=geom)
    try:
        for span in spans:
            _fill(span)
    finally:
        _JOB.clear()
    return out


def _source_grid(size: int, rot: torch.Tensor, flip: torch.Tensor
                 ) -> tuple[torch.Tensor, torch.Tensor]:
    """(rows, columns), each (B, size, size): where each output pixel of ``rot`` counter-
    clockwise quarter turns (``np.rot90``) of a horizontally flipped (``flip``) image comes
    from, in that image before the flip."""
    b = len(rot)
    ar = torch.arange(size, device=rot.device)
    ys = ar.view(1, size, 1).expand(b, size, size)
    xs = ar.view(1, 1, size).expand(b, size, size)
    for q in range(1, 4):  # rot90: out[y, x] = in[x, size - 1 - y]
        sel = (rot >= q).view(b, 1, 1)
        ys, xs = torch.where(sel, xs, ys), torch.where(sel, size - 1 - ys, xs)
    xs = torch.where(flip.view(b, 1, 1).bool(), size - 1 - xs, xs)
    return ys, xs


def _gather(img: torch.Tensor, rows: torch.Tensor, cols: torch.Tensor, width: int
            ) -> torch.Tensor:
    """img (B, C, H, width) sampled at integer (rows, cols) (B, h, w) -> (B, C, h, w)."""
    b, c = img.shape[:2]
    h, w = rows.shape[1:]
    flat = (rows * width + cols).view(b, 1, h * w).expand(b, c, h * w)
    return img.reshape(b, c, -1).gather(2, flat).view(b, c, h, w)


def normalize_batch(img: torch.Tensor) -> torch.Tensor:
    """``data.normalize_rgbd`` of a (B, 4, S, S) batch of (depth m, R, G, B 0-255) with finite
    depth: depth minus its mean, RGB / 255 minus the mean of all three channels."""
    d = img[:, :1]
    c = img[:, 1:] / 255.0
    return torch.cat([d - d.mean(dim=(1, 2, 3), keepdim=True),
                      c - c.mean(dim=(1, 2, 3), keepdim=True)], dim=1)


class DeviceImages:
    """Packs' images and label canvases on one device, and their augmented batches."""

    def __init__(self, packs: list[Pack], device: torch.device, sizes: list[int],
                 workers: int = 1, log=None):
        if not packs:
            raise ValueError("no pack given")
        n = packs[0].size
        if any(p.size != n for p in packs):
            raise ValueError(f"packs of different crop sides: {[p.size for p in packs]}")
        self.n = n
        self.device = device
        self.geoms = {s: CanvasGeometry(n, s) for s in sorted(set(sizes))}
        for g in self.geoms.values():
            g.check()
        positives = [r for p in packs for r in p.positives]
        negatives = [r for p in packs for r in p.negatives]
        canvases = {}
        for s, g in self.geoms.items():  # before any CUDA work: the workers fork
            canvases[s] = label_canvases(positives, negatives, g, workers)
            if log:
                log(f"label canvases for {s} px: {canvases[s].nbytes / 2**30:.2f} GiB")
        self.rgb = torch.cat([torch.from_numpy(p.rgb).to(device).permute(0, 3, 1, 2)
                              for p in packs]).contiguous()
        self.depth = torch.cat([torch.from_numpy(p.depth).to(device) for p in packs])
        self.canvases = {}
        for s, c in canvases.items():
            t = torch.empty(c.shape, dtype=torch.float32, device=device)
            for i in range(0, len(c), 256):
                t[i:i + 256] = torch.from_numpy(c[i:i + 256]).to(device)
            self.canvases[s] = t
        del canvases

    def __len__(self) -> int:
        return len(self.rgb)

    def draw(self, count: int, seed: int, epoch: int, augment: bool = True
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(quarter turns, flips, shifts (count, 2) as dx, dy) of one epoch."""
        if not augment:
            return (np.zeros(count, np.int64), np.zeros(count, np.int64),
                    np.zeros((count, 2), np.int64))
        rng = np.random.default_rng([seed, epoch, 0x6770])
        m = round(SHIFT_FRACTION * self.n)
        return (rng.integers(0, 4, count), rng.integers(0, 2, count),
                rng.integers(-m, m + 1, (count, 2)))

    def batch(self, idx: torch.Tensor, rot: torch.Tensor, flip: torch.Tensor,
              shift: torch.Tensor, sizes: list[int], target_sizes: list[int] | None = None
              ) -> dict[int, tuple[torch.Tensor, torch.Tensor | None]]:
        """{size: (inputs (B, 4, size, size), targets (B, 5, size, size))} of images ``idx``
        shifted by ``shift`` (dx, dy), flipped, turned (all long tensors on the device);
        targets only for ``target_sizes`` (default: every size), else None."""
        n = self.n
        img = torch.cat([self.depth[idx].unsqueeze(1), self.rgb[idx].float()], dim=1)
        ys, xs = _source_grid(n, rot, flip)
        dx = shift[:, 0].view(-1, 1, 1)
        dy = shift[:, 1].view(-1, 1, 1)
        img = _gather(img, (ys - dy).clamp(0, n - 1), (xs - dx).clamp(0, n - 1), n)
        d = img[:, 0]
        ok = torch.isfinite(d)
        fill = torch.where(ok, d, 0.0).sum(dim=(1, 2)) / ok.sum(dim=(1, 2)).clamp(min=1)
        img = torch.cat([torch.where(ok, d, fill.view(-1, 1, 1)).unsqueeze(1), img[:, 1:]], 1)
        out = {}
        for s in sizes:
            g = self.geoms[s]
            f = g.factor
            x = F.avg_pool2d(img, f, stride=f) if f > 1 else img
            if target_sizes is not None and s not in target_sizes:
                out[s] = (normalize_batch(x), None)
                continue
            kx = torch.div(dx, f, rounding_mode="floor")
            ky = torch.div(dy, f, rounding_mode="floor")
            which = ((dy - ky * f) * f + (dx - kx * f)).view(-1)
            canvas = self.canvases[s][idx, which]
            ts, tx = _source_grid(s, rot, flip)
            y = _gather(canvas, ts - ky + g.pad, tx - kx + g.pad, g.side)
            turn = 1.0 - 2.0 * (rot % 2).to(y.dtype)
            mirror = 1.0 - 2.0 * flip.to(y.dtype)
            y = torch.cat([y[:, :1], y[:, 1:2] * turn.view(-1, 1, 1, 1),
                           y[:, 2:3] * (turn * mirror).view(-1, 1, 1, 1), y[:, 3:]], dim=1)
            out[s] = (normalize_batch(x), y)
        return out


def teacher_targets(maps: GraspMaps, size: int) -> torch.Tensor:
    """(B, 4, size, size) float32: a network's maps at another input size's resolution (area
    averaged), the width map scaled with the input (widths are input pixels)."""
    t = torch.stack([m.float() for m in maps], dim=1)
    side = t.shape[-1]
    if side != size:
        if side % size:
            raise ValueError(f"teacher maps of {side} px do not reduce to {size} px")
        t = F.avg_pool2d(t, side // size)
        t = torch.cat([t[:, :3], t[:, 3:] * (size / side)], dim=1)
    return t


class OnDevice(nn.Module):
    """A model that takes CPU batches and returns CPU float32 maps (what
    ``training.evaluate_model`` expects) while it runs on ``device``."""

    def __init__(self, model: nn.Module, device: torch.device):
        super().__init__()
        self.model = model
        self.device = device

    def forward(self, x: torch.Tensor) -> GraspMaps:
        x = x.to(self.device, non_blocking=True)
        if self.device.type == "cuda":
            x = x.contiguous(memory_format=torch.channels_last)
        return GraspMaps(*(m.float().cpu() for m in self.model(x)))


def cpu_state(model: nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}


def finite_state(state: dict[str, torch.Tensor]) -> bool:
    return all(bool(torch.isfinite(v).all()) for v in state.values() if v.is_floating_point())


def default_workers() -> int:
    return max(1, min(32, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                      else os.cpu_count() or 1))
