"""Time training and inference per image for a configuration.

    python -m train_ae.bench --config cpu [--steps 5] [--batch-size 8] [--infer-batch 16]
        [--threads 2] [--data DIR]

Three figures, each the median over ``--steps`` timed repetitions after one untimed warm-up, so
a burst of load from other processes counts less:

* training, model only: one optimiser step (Adam, weighted loss: the training defaults) on a
  batch of random inputs, divided by the batch size;
* training on 224-px crops: the same step including what ``train`` does per batch — reading the
  PNG/TIFF crops and their rectangles, augmentation (shift, flip, rotation), the resize to the
  input size (224 -> 112 for ``cpu``) and the label maps. The crops are the synthetic lgdm-layout
  fixture (``train_ae.synthetic``, 224 x 224) unless ``--data`` names a dataset;
* inference per crop: ``bridge.preprocess(rgb, depth, input_size)`` of each 224-px crop plus
  ``bridge.infer`` (features and the four maps, plain Python) at batch 1 and ``--infer-batch``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from . import bridge
from .data import GraspDataset, find_samples, load_images
from .model import GraspAutoencoder, ModelConfig, parameter_count
from .synthetic import write_synthetic_dataset
from .training import grasp_loss, make_optimizer


def _median_per_image(times: list[float], n: int) -> float:
    return statistics.median(times) / n


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", choices=["cpu", "paper"], default="cpu")
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--infer-batch", type=int, default=16)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--data", type=Path, help="dataset of crops (default: synthetic 224-px)")
    a = p.parse_args(argv)
    if a.steps < 1 or a.batch_size < 1 or a.infer_batch < 1:
        p.error("--steps, --batch-size and --infer-batch must be at least 1")
    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    cfg = ModelConfig.preset(a.config)
    model = GraspAutoencoder(cfg)
    s, b = cfg.input_size, a.batch_size
    gen = torch.Generator().manual_seed(a.seed)
    x = torch.randn(b, 4, s, s, generator=gen)
    y = torch.zeros(b, 4, s, s)
    y[:, :, s // 3:s // 2, s // 3:s // 2] = torch.rand(b, 4, 1, 1, generator=gen)
    opt = make_optimizer("adam", model.parameters(), 1e-3)
    model.train()
    times = []
    for i in range(a.steps + 1):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        grasp_loss(model(x), y).backward()
        opt.step()
        if i:
            times.append(time.perf_counter() - t0)
    train_model_s = _median_per_image(times, b)

    with tempfile.TemporaryDirectory(prefix="train_ae-bench-") as tmp:
        n_crops = max(b * (a.steps + 1), a.infer_batch)
        root = a.data or write_synthetic_dataset(Path(tmp) / "crops", objects=4,
                                                 images_per_object=(n_crops + 3) // 4,
                                                 seed=a.seed)
        samples = find_samples(root)
        crop_side = load_images(samples[0])[1].shape[0]
        ds = GraspDataset(samples, s, augment=True, seed=a.seed)
        model.train()
        times = []
        for i in range(a.steps + 1):
            idx = [(i * b + j) % len(ds) for j in range(b)]
            t0 = time.perf_counter()
            xb, yb, _ = ds.batch(idx, epoch=0)
            opt.zero_grad(set_to_none=True)
            grasp_loss(model(xb), yb).backward()
            opt.step()
            if i:
                times.append(time.perf_counter() - t0)
        train_data_s = _median_per_image(times, b)

        model.eval()
        crops = [load_images(samples[i % len(samples)]) for i in range(a.infer_batch)]
        inf = {}
        for n in (1, a.infer_batch):
            ts = []
            for i in range(a.steps + 1):
                t0 = time.perf_counter()
                batch = np.stack([bridge.preprocess(rgb, depth, s) for rgb, depth in crops[:n]])
                bridge.infer(model, batch)
                if i:
                    ts.append(time.perf_counter() - t0)
            inf[n] = _median_per_image(ts, n)

    print(f"config {cfg.name}: {parameter_count(model):,} parameters, input {s}x{s}, "
          f"{a.threads} threads")
    print(f"training, model only: {train_model_s:.3f} s per image (batch {b}, Adam, weighted "
          f"loss, random inputs, median of {a.steps} steps)")
    print(f"training on {crop_side}-px crops -> {s}: {train_data_s:.3f} s per image (batch {b}, "
          f"loading, augmentation, resize, labels and the step; median of {a.steps} steps)")
    for n, t in inf.items():
        print(f"inference per {crop_side}-px crop (bridge.preprocess + bridge.infer, plain "
              f"Python): {t:.3f} s at batch {n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
