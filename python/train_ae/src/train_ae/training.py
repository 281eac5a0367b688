"""Training and evaluation loops (library side: no printing; progress through a callback).

Example::

    model = GraspAutoencoder(ModelConfig.preset("cpu"))
    history = train_model(model, train_ds, epochs=2, batch_size=8, lr=1e-3, seed=0)
    result = evaluate_model(model, held_out_ds, jaw_side_fraction=0.0909)  # {"n", "correct", ...}

Departures from the paper (which trains with RMSprop on the plain sum of four smooth-L1 losses;
that is still ``loss="paper", optimizer="rmsprop"``): by default the loss is *weighted* toward
positive pixels and the optimiser is Adam. With positives ~1-7 % of the pixels, the plain mean
lets "no grasp anywhere" win (a network that predicts zeros everywhere is close to the minimum),
and the width map collapsed to ~0 on thin bowl rims when only the quality term was weighted.
Adam at 1e-3 with positives weighted x10 reached 84.5 % on held-out objects in the experiment of
``docs/DESIGN.md`` §5, where the paper's settings gave 20 %.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from .data import GraspDataset
from .grasp import decode_grasps, is_correct, jaw_px_for, wilson_interval
from .model import GraspAutoencoder, GraspMaps

ProgressFn = Callable[[int, int, int, float], None]
"""progress(epoch, batches_done, batches_total, batch_loss); called with 0 done (loss NaN) at
the start of each epoch."""


LOSSES = ("weighted", "paper")
OPTIMIZERS = ("adam", "rmsprop")
DEFAULT_POS_WEIGHT = 10.0
"""Weight of a positive pixel (target quality > 0) relative to a negative one."""
DEFAULT_NEG_WEIGHT = 1.0
"""Weight of the quality term at a labelled failure (``negative_map``) relative to an
unlabelled pixel; 1 = failures count as any other pixel without a positive label."""
DEFAULT_WIDTH_WEIGHT = 1.0
"""Factor on the width term of the weighted loss (1: the four terms count alike)."""


BALANCE_LIMIT = 4.0
"""``balance_images``: an image's positive weight is scaled by at most this factor either way."""


def grasp_loss(maps: GraspMaps, targets: torch.Tensor, loss: str = "weighted",
               pos_weight: float = DEFAULT_POS_WEIGHT, neg_weight: float = DEFAULT_NEG_WEIGHT,
               width_weight: float = DEFAULT_WIDTH_WEIGHT,
               balance_images: bool = False) -> torch.Tensor:
    """The grasp loss over the four maps; ``targets`` is (N, 4 or 5, H, W) = quality, cos 2θ,
    sin 2θ, width and optionally the negative mask (``GraspDataset`` gives all five).

    ``"paper"``: the paper's sum over the four maps of the plain mean smooth-L1 loss (the
    negative mask is ignored).
    ``"weighted"`` (the default; a departure from the paper): per-pixel weight
    w = 1 + (pos_weight - 1)·[target quality > 0], and each of the four terms is
    Σ w·smoothL1 / Σ w — the angle and width terms are weighted too, not only quality. The
    quality term alone weighs a pixel of the negative mask by ``neg_weight`` instead of 1
    (w_q = w + (neg_weight - 1)·negative): a grasp known to fail there, not an untried spot.
    The width term is multiplied by ``width_weight``: the opening is what decides whether a
    grasp on a lid or a rim holds, and its term is the smallest of the four.
    ``balance_images``: the extra weight of an image's positive pixels is scaled by P̄ / P_i
    (P_i its positive pixels, P̄ the mean over the batch's images that have any; clamped to
    [1 / ``BALANCE_LIMIT``, ``BALANCE_LIMIT``]), so an object the labeller accepts two pinches
    on weighs about as much as one with forty grasps.
    """
    if loss == "paper":
        return sum(F.smooth_l1_loss(m, targets[:, i]) for i, m in enumerate(maps))
    if loss != "weighted":
        raise ValueError(f"unknown loss {loss!r}: expected one of {LOSSES}")
    if not pos_weight > 0:
        raise ValueError(f"pos_weight must be positive, got {pos_weight}")
    if not neg_weight > 0:
        raise ValueError(f"neg_weight must be positive, got {neg_weight}")
    if not width_weight > 0:
        raise ValueError(f"width_weight must be positive, got {width_weight}")
    positive = (targets[:, 0] > 0).to(targets.dtype)
    scale = torch.ones(len(targets), 1, 1, dtype=targets.dtype, device=targets.device)
    if balance_images:
        count = positive.sum(dim=(1, 2))
        has = count > 0
        if has.any():
            ratio = count[has].mean() / count.clamp(min=1.0)
            scale = torch.where(has, ratio.clamp(1 / BALANCE_LIMIT, BALANCE_LIMIT),
                                torch.ones_like(ratio))[:, None, None]
    w = 1.0 + (pos_weight - 1.0) * positive * scale
    w_q = w
    if targets.shape[1] > 4 and neg_weight != 1.0:
        w_q = w + (neg_weight - 1.0) * targets[:, 4]
    total = 0.0
    for i, m in enumerate(maps):
        wi = w_q if i == 0 else w
        term = (wi * F.smooth_l1_loss(m, targets[:, i], reduction="none")).sum() / wi.sum()
        total = total + (width_weight * term if i == 3 else term)
    return total


def make_optimizer(name: str, params, lr: float) -> torch.optim.Optimizer:
    """``adam`` (default: a departure from the paper) or ``rmsprop`` (the paper's), PyTorch's
    defaults otherwise."""
    if name == "adam":
        return torch.optim.Adam(params, lr=lr)
    if name == "rmsprop":
        return torch.optim.RMSprop(params, lr=lr)
    raise ValueError(f"unknown optimizer {name!r}: expected one of {OPTIMIZERS}")


@dataclass
class TrainHistory:
    epoch_loss: list[float] = field(default_factory=list)
    """Mean training loss of each epoch."""
    images: int = 0
    seconds: float = 0.0
    """Wall-clock time of the optimisation steps including data loading."""


def train_model(model: GraspAutoencoder, dataset: GraspDataset, epochs: int, batch_size: int = 8,
                lr: float = 1e-3, seed: int = 0, progress: ProgressFn | None = None,
                start_epoch: int = 0, max_steps: int | None = None, loss: str = "weighted",
                pos_weight: float = DEFAULT_POS_WEIGHT, optimizer: str = "adam",
                neg_weight: float = DEFAULT_NEG_WEIGHT,
                width_weight: float = DEFAULT_WIDTH_WEIGHT,
                balance_images: bool = False) -> TrainHistory:
    """``optimizer`` (Adam by default, RMSprop = the paper) on ``grasp_loss(loss,
    pos_weight, neg_weight, width_weight)``; batch order seeded by (seed, epoch).

    The caller seeds torch before building the model (initial weights) and may make torch
    deterministic; with the same thread count the result is then bit-for-bit reproducible.
    """
    if len(dataset) == 0:
        raise ValueError("no training images")
    if epochs < 0 or batch_size < 1 or lr <= 0:
        raise ValueError(f"bad training settings: epochs={epochs}, batch_size={batch_size}, "
                         f"lr={lr}")
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}: expected one of {LOSSES}")
    opt = make_optimizer(optimizer, model.parameters(), lr)
    hist = TrainHistory()
    n = len(dataset)
    batches = (n + batch_size - 1) // batch_size
    steps = 0
    t0 = time.perf_counter()
    for epoch in range(start_epoch, start_epoch + epochs):
        model.train()
        order = np.random.default_rng([seed, epoch]).permutation(n)
        total, count = 0.0, 0
        if progress is not None:
            progress(epoch, 0, batches, float("nan"))
        for b in range(batches):
            idx = order[b * batch_size:(b + 1) * batch_size].tolist()
            x, y, _ = dataset.batch(idx, epoch)
            opt.zero_grad(set_to_none=True)
            value = grasp_loss(model(x), y, loss, pos_weight, neg_weight, width_weight,
                               balance_images)
            value.backward()
            opt.step()
            loss_value = value.item()
            total += loss_value * len(idx)
            count += len(idx)
            hist.images += len(idx)
            steps += 1
            if progress is not None:
                progress(epoch, b + 1, batches, loss_value)
            if max_steps is not None and steps >= max_steps:
                break
        hist.epoch_loss.append(total / max(count, 1))
        if max_steps is not None and steps >= max_steps:
            break
    hist.seconds = time.perf_counter() - t0
    return hist


LABEL_COUNT_BINS = (("1-6", 6), ("7-15", 15), ("16+", float("inf")))
"""Bins of an image's number of labelled (positive) rectangles in ``per_label_count``: an object
the labeller accepts few grasps on (an apple wider than the stroke: a pinch or two) is scored
against those few."""


def evaluate_model(model: GraspAutoencoder, dataset: GraspDataset, batch_size: int = 8,
                   progress: Callable[[int, int], None] | None = None,
                   jaw_side_fraction: float | None = None) -> dict:
    """Rectangle metric of the top-1 decoded grasp per image, with a 95 % Wilson interval.

    Decoded jaws are ``jaw_side_fraction`` x the map side (lgdm data: the finger width), or
    opening x ``JAW_FRACTION`` when it is None (the real Cornell set).

    Images without any positive rectangle cannot be scored and are counted in
    ``skipped_no_ground_truth`` instead of ``n``. An image where no grasp reaches the quality
    threshold counts as incorrect.
    """
    model.eval()
    n = correct = skipped = no_grasp = 0
    per_category: dict[str, list[int]] = {}
    per_object: dict[str, list[int]] = {}
    per_labels: dict[str, list[int]] = {name: [0, 0] for name, _ in LABEL_COUNT_BINS}
    total = len(dataset)
    with torch.inference_mode():
        for start in range(0, total, batch_size):
            idx = list(range(start, min(start + batch_size, total)))
            x, _, rects = dataset.batch(idx, epoch=0)
            maps = model(x)
            for j, gt in enumerate(rects):
                if not gt:
                    skipped += 1
                    continue
                q = maps[0][j].numpy()
                pred = decode_grasps(*(m[j].numpy() for m in maps), num_grasps=1,
                                     jaw_px=jaw_px_for(jaw_side_fraction, q.shape[-1]))
                ok = int(bool(pred) and is_correct(pred[0], gt))
                n += 1
                correct += ok
                no_grasp += int(not pred)
                sample = dataset.samples[idx[j]]
                labels = next(name for name, top in LABEL_COUNT_BINS if len(gt) <= top)
                for key, table in ((sample.category or "-", per_category),
                                   (sample.object_id, per_object), (labels, per_labels)):
                    table.setdefault(key, [0, 0])
                    table[key][0] += ok
                    table[key][1] += 1
            if progress is not None:
                progress(idx[-1] + 1, total)
    lo, hi = wilson_interval(correct, n)
    return {
        "n": n,
        "correct": correct,
        "accuracy": correct / n if n else None,
        "ci95": [lo, hi],
        "skipped_no_ground_truth": skipped,
        "no_grasp": no_grasp,
        "per_category": {k: {"correct": v[0], "n": v[1]} for k, v in sorted(per_category.items())},
        "per_object": {k: {"correct": v[0], "n": v[1]} for k, v in sorted(per_object.items())},
        "per_label_count": {k: {"correct": v[0], "n": v[1]} for k, v in per_labels.items()},
    }


def format_result(result: dict) -> str:
    n, k = result["n"], result["correct"]
    if not n:
        return "rectangle metric: n = 0 (no scorable images)"
    lo, hi = result["ci95"]
    text = (f"rectangle metric (top-1 grasp, IoU > 0.25 and |Δθ| ≤ 30°): {k}/{n} = "
            f"{100 * k / n:.1f} % (95 % Wilson CI {100 * lo:.1f}–{100 * hi:.1f} %), n = {n}")
    if result.get("no_grasp"):
        text += f"; no grasp above the threshold on {result['no_grasp']}"
    cats = result.get("per_category") or {}
    if len(cats) > 1 or (cats and "-" not in cats):
        text += "\n  per category: " + ", ".join(
            f"{c} {v['correct']}/{v['n']}" for c, v in cats.items())
    bins = result.get("per_label_count") or {}
    if sum(v["n"] for v in bins.values()):
        text += "\n  per labelled grasps in the image: " + ", ".join(
            f"{c} {v['correct']}/{v['n']}" for c, v in bins.items() if v["n"])
    return text
