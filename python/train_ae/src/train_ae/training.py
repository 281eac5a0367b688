"""Training and evaluation loops (library side: no printing; progress through a callback).

Example::

    model = GraspAutoencoder(ModelConfig.preset("cpu"))
    history = train_model(model, train_ds, epochs=2, batch_size=8, lr=1e-3, seed=0)
    result = evaluate_model(model, held_out_ds)      # {"n", "correct", "accuracy", "ci95", ...}
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from .data import GraspDataset
from .grasp import decode_grasps, is_correct, wilson_interval
from .model import GraspAutoencoder, GraspMaps

ProgressFn = Callable[[int, int, int, float], None]
"""progress(epoch, batches_done, batches_total, batch_loss); called with 0 done (loss NaN) at
the start of each epoch."""


def grasp_loss(maps: GraspMaps, targets: torch.Tensor) -> torch.Tensor:
    """Sum over the four maps of the mean smooth-L1 loss; ``targets`` is (N, 4, H, W)."""
    return sum(F.smooth_l1_loss(m, targets[:, i]) for i, m in enumerate(maps))


@dataclass
class TrainHistory:
    epoch_loss: list[float] = field(default_factory=list)
    """Mean training loss of each epoch."""
    images: int = 0
    seconds: float = 0.0
    """Wall-clock time of the optimisation steps including data loading."""


def train_model(model: GraspAutoencoder, dataset: GraspDataset, epochs: int, batch_size: int = 8,
                lr: float = 1e-3, seed: int = 0, progress: ProgressFn | None = None,
                start_epoch: int = 0, max_steps: int | None = None) -> TrainHistory:
    """RMSprop on the summed smooth-L1 grasp loss; batch order seeded by (seed, epoch).

    The caller seeds torch before building the model (initial weights) and may make torch
    deterministic; with the same thread count the result is then bit-for-bit reproducible.
    """
    if len(dataset) == 0:
        raise ValueError("no training images")
    if epochs < 0 or batch_size < 1 or lr <= 0:
        raise ValueError(f"bad training settings: epochs={epochs}, batch_size={batch_size}, "
                         f"lr={lr}")
    opt = torch.optim.RMSprop(model.parameters(), lr=lr)
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
            loss = grasp_loss(model(x), y)
            loss.backward()
            opt.step()
            loss_value = loss.item()
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


def evaluate_model(model: GraspAutoencoder, dataset: GraspDataset, batch_size: int = 8,
                   progress: Callable[[int, int], None] | None = None) -> dict:
    """Rectangle metric of the top-1 decoded grasp per image, with a 95 % Wilson interval.

    Images without any positive rectangle cannot be scored and are counted in
    ``skipped_no_ground_truth`` instead of ``n``. An image where no grasp reaches the quality
    threshold counts as incorrect.
    """
    model.eval()
    n = correct = skipped = 0
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
                pred = decode_grasps(*(m[j].numpy() for m in maps), num_grasps=1)
                n += 1
                correct += int(bool(pred) and is_correct(pred[0], gt))
            if progress is not None:
                progress(idx[-1] + 1, total)
    lo, hi = wilson_interval(correct, n)
    return {
        "n": n,
        "correct": correct,
        "accuracy": correct / n if n else None,
        "ci95": [lo, hi],
        "skipped_no_ground_truth": skipped,
    }


def format_result(result: dict) -> str:
    n, k = result["n"], result["correct"]
    if not n:
        return "rectangle metric: n = 0 (no scorable images)"
    lo, hi = result["ci95"]
    return (f"rectangle metric (top-1 grasp, IoU > 0.25 and |Δθ| ≤ 30°): {k}/{n} = "
            f"{100 * k / n:.1f} % (95 % Wilson CI {100 * lo:.1f}–{100 * hi:.1f} %), n = {n}")
