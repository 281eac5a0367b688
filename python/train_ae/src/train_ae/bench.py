"""Time training and inference per image for a configuration (random inputs, no data loading).

    python -m train_ae.bench --config cpu [--steps 5] [--batch-size 8] [--threads 2]

Training: RMSprop steps on the summed smooth-L1 loss, after one untimed warm-up step; the figure
is wall-clock seconds divided by images. Inference: ``bridge.infer`` (features and the four maps,
eval mode, inference_mode) at batch 1 and at the training batch size, after one warm-up call.
Reports the median over steps, so a burst of load from other processes counts less.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch

from . import bridge
from .model import GraspAutoencoder, ModelConfig, parameter_count
from .training import grasp_loss


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", choices=["cpu", "paper"], default="cpu")
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    cfg = ModelConfig.preset(a.config)
    model = GraspAutoencoder(cfg)
    s, b = cfg.input_size, a.batch_size
    gen = torch.Generator().manual_seed(a.seed)
    x = torch.randn(b, 4, s, s, generator=gen)
    y = torch.rand(b, 4, s, s, generator=gen)
    opt = torch.optim.RMSprop(model.parameters(), lr=1e-3)
    model.train()
    times = []
    for i in range(a.steps + 1):
        t0 = time.perf_counter()
        opt.zero_grad(set_to_none=True)
        grasp_loss(model(x), y).backward()
        opt.step()
        if i:
            times.append(time.perf_counter() - t0)
    train_s = statistics.median(times) / b
    model.eval()
    xs = x.numpy()
    inf = {}
    for n in (1, b):
        batch = np.ascontiguousarray(xs[:n])
        bridge.infer(model, batch)
        ts = []
        for _ in range(a.steps):
            t0 = time.perf_counter()
            bridge.infer(model, batch)
            ts.append(time.perf_counter() - t0)
        inf[n] = statistics.median(ts) / n
    print(f"config {cfg.name}: {parameter_count(model):,} parameters, input {s}x{s}, "
          f"{a.threads} threads")
    print(f"training: {train_s:.3f} s per image (batch {b}, median of {a.steps} steps)")
    for n, t in inf.items():
        print(f"inference (bridge.infer, plain Python): {t:.3f} s per image at batch {n}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
