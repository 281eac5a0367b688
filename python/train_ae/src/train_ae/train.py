"""Train the grasp autoencoder on a Cornell-layout directory and evaluate it on held-out objects.

    python -m train_ae.train --data DIR --config cpu --epochs N --out CKPT
        [--batch-size 8] [--lr 1e-3] [--seed 0] [--val-fraction 0.1] [--object-map FILE]
        [--threads 2] [--no-augment] [--quiet]

Whole objects (``<nn>`` folders, or the ids of --object-map) are held out; the network of the
FINAL epoch is scored on them with the rectangle metric (n and a 95 % Wilson interval). Nothing
on the held-out objects chooses an epoch or a setting. Same seed and thread count -> same
checkpoint bytes.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import torch

from .checkpoint import save_checkpoint
from .data import DatasetError, GraspDataset, find_samples, read_object_map, split_by_object
from .model import GraspAutoencoder, ModelConfig, parameter_count
from .progress import ProgressBar
from .training import evaluate_model, format_result, train_model


def _args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m train_ae.train", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path, help="Cornell-layout dataset directory")
    p.add_argument("--config", choices=["cpu", "paper"], default="cpu")
    p.add_argument("--epochs", type=int, required=True)
    p.add_argument("--out", required=True, type=Path, help="checkpoint file to write")
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--val-fraction", type=float, default=0.1,
                   help="fraction of objects held out for the final evaluation (default 0.1)")
    p.add_argument("--object-map", type=Path, help="file of '<stem> <object id>' lines")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    p.add_argument("--no-augment", action="store_true", help="no random rotation and zoom")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    a = p.parse_args(argv)
    if a.epochs < 1:
        p.error("--epochs must be at least 1")
    if a.batch_size < 1:
        p.error("--batch-size must be at least 1")
    if a.lr <= 0:
        p.error("--lr must be positive")
    if not 0 <= a.val_fraction < 1:
        p.error("--val-fraction must be in [0, 1)")
    if a.threads < 1:
        p.error("--threads must be at least 1")
    return a


def run(a: argparse.Namespace) -> dict:
    torch.set_num_threads(a.threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(a.seed)
    object_map = read_object_map(a.object_map) if a.object_map else None
    samples = find_samples(a.data, object_map)
    train_s, held_s = split_by_object(samples, a.val_fraction, a.seed)
    config = ModelConfig.preset(a.config)
    model = GraspAutoencoder(config)
    train_objects = sorted({s.object_id for s in train_s})
    held_objects = sorted({s.object_id for s in held_s})
    log = sys.stderr
    print(f"config {config.name}: {parameter_count(model):,} parameters, input "
          f"{config.input_size}x{config.input_size}; {len(train_s)} training images of "
          f"{len(train_objects)} objects, {len(held_s)} held-out images of {len(held_objects)} "
          f"objects {held_objects}", file=log)
    train_ds = GraspDataset(train_s, config.input_size, augment=not a.no_augment, seed=a.seed)
    bars: dict[int, ProgressBar] = {}

    def progress(epoch: int, done: int, total: int, loss: float) -> None:
        bar = bars.get(epoch)
        if bar is None:
            bar = bars[epoch] = ProgressBar(total, f"epoch {epoch + 1}/{a.epochs}",
                                            stream=log, enabled=not a.quiet)
        if done == 0:
            return
        bar.update(1, loss=loss)
        if done == total:
            bar.close()

    hist = train_model(model, train_ds, a.epochs, a.batch_size, a.lr, a.seed, progress)
    s_per_img = hist.seconds / max(hist.images, 1)
    print(f"trained {a.epochs} epochs in {hist.seconds:.1f} s ({s_per_img:.3f} s per image, "
          f"{a.threads} threads); final epoch loss {hist.epoch_loss[-1]:.4f}", file=log)

    heldout = None
    if held_s:
        ds = GraspDataset(held_s, config.input_size, augment=False)
        t0 = time.perf_counter()
        heldout = evaluate_model(model, ds)
        heldout["objects"] = held_objects
        print(f"held-out objects, final epoch {a.epochs}: {format_result(heldout)} "
              f"[{time.perf_counter() - t0:.1f} s]", file=log)
    else:
        print("no held-out objects (fewer than two objects or --val-fraction 0): "
              "no evaluation", file=log)
    metrics = {
        "training": {
            "data": str(a.data),
            "epochs": a.epochs,
            "batch_size": a.batch_size,
            "lr": a.lr,
            "optimizer": "RMSprop",
            "seed": a.seed,
            "val_fraction": a.val_fraction,
            "augment": not a.no_augment,
            "threads": a.threads,
            "train_objects": train_objects,
            "train_images": len(train_s),
            "epoch_loss": hist.epoch_loss,
        },
        "heldout": heldout,
    }
    save_checkpoint(a.out, model, metrics)
    print(f"wrote {a.out}", file=log)
    return metrics


def main(argv: list[str] | None = None) -> int:
    a = _args(argv)
    try:
        run(a)
    except (DatasetError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
