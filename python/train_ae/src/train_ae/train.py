"""Train the grasp autoencoder on a Cornell-layout directory and evaluate it on held-out objects.

    python -m train_ae.train --data DIR [DIR ...] --config cpu --epochs N --out CKPT
        [--init CKPT] [--input-size PX] [--batch-size 8] [--lr 1e-3] [--optimizer adam|rmsprop]
        [--loss weighted|paper] [--pos-weight 10] [--neg-weight 1] [--width-weight 1]
        [--balance-images]
        [--seed 0] [--holdout per-category|fraction|init] [--per-category 1]
        [--repeat DIR=K ...]
        [--val-fraction 0.1]
        [--object-map FILE] [--threads 2] [--no-augment] [--quiet]

Whole objects are held out: by default one instance per category (``--holdout per-category``,
when the lgdm ``index.json`` gives categories), else a seeded ``--val-fraction`` of all objects
(``--holdout fraction``; the real Cornell set, where objects are ``<nn>`` folders or the ids of
--object-map). The network of the FINAL epoch is scored on them with the rectangle metric (n and
a 95 % Wilson interval), decoding jaws as the training data's index says (the finger width) or,
without one, as opening / 2. Nothing on the held-out objects chooses an epoch or a setting.

Defaults depart from the paper (RMSprop, plain smooth-L1 sum: ``--optimizer rmsprop --loss
paper``): Adam and a loss weighting positive pixels ×10 (see ``train_ae.training``).

Several ``--data`` directories train as one set (e.g. ``gen-dataset``'s geometric labels and
``lgdm sim grasp-data``'s physics labels): an object name held out is held out of every one.
``--init CKPT`` starts from a checkpoint's weights (its configuration must be ``--config``'s)
instead of a seeded initialisation: a fine-tune; the checkpoint's file name and sha256 are
recorded in the new one's metrics. A fine-tune holds out the objects its checkpoint held out
(``--holdout init``, the default with ``--init``), so its held-out score is on objects neither
stage trained on.

``--input-size PX`` trains at another input size than ``--config``'s (with ``--init``: than the
checkpoint's, whose weights all still fit — the feature is pooled adaptively — and whose width
head is scaled by the ratio, widths being input pixels).

``--balance-images`` (weighted loss) scales each image's extra positive weight by the batch's
mean positive area over the image's own, clamped to [1/4, 4]: an image the labeller accepts one
or two pinches on counts about as much as one with forty grasps.

``--repeat DIR=K`` shows the training images of one ``--data`` directory K times per epoch
(e.g. the robot's own views among many geometric images); held-out images are scored once.

Same seed and thread count (and ``--init`` file) -> same checkpoint bytes.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import sys
import time
from pathlib import Path

import torch

from .checkpoint import load_checkpoint, save_checkpoint
from .data import (
    DatasetError,
    GraspDataset,
    Sample,
    find_samples_in,
    read_object_map,
    split_by_object,
    split_held_out_instances,
)
from .model import GraspAutoencoder, ModelConfig, parameter_count, rescale_widths
from .progress import ProgressBar
from .training import (
    DEFAULT_NEG_WEIGHT,
    DEFAULT_POS_WEIGHT,
    DEFAULT_WIDTH_WEIGHT,
    LOSSES,
    OPTIMIZERS,
    evaluate_model,
    format_result,
    train_model,
)


def _args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m train_ae.train", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path, nargs="+", metavar="DIR",
                   help="Cornell-layout dataset directories (several train as one set)")
    p.add_argument("--config", choices=["cpu", "paper"], default="cpu")
    p.add_argument("--epochs", type=int, required=True)
    p.add_argument("--input-size", type=int, default=None, metavar="PX",
                   help="side of the network's input in pixels (default: --init's, else "
                        "--config's: cpu 112, paper 224); a multiple of 4")
    p.add_argument("--out", required=True, type=Path, help="checkpoint file to write")
    p.add_argument("--init", type=Path, metavar="CKPT",
                   help="start from this checkpoint's weights (a fine-tune) instead of a "
                        "seeded initialisation")
    p.add_argument("--batch-size", type=int, default=8)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--optimizer", choices=OPTIMIZERS, default="adam",
                   help="adam (default) or rmsprop (the paper's)")
    p.add_argument("--loss", choices=LOSSES, default="weighted",
                   help="weighted (default: positives x --pos-weight in all four terms) or "
                        "paper (sum of four plain smooth-L1 means)")
    p.add_argument("--pos-weight", type=float, default=DEFAULT_POS_WEIGHT,
                   help=f"weight of positive pixels for --loss weighted (default "
                        f"{DEFAULT_POS_WEIGHT:g})")
    p.add_argument("--width-weight", type=float, default=DEFAULT_WIDTH_WEIGHT,
                   help="factor on the width term of --loss weighted (default "
                        f"{DEFAULT_WIDTH_WEIGHT:g})")
    p.add_argument("--neg-weight", type=float, default=DEFAULT_NEG_WEIGHT,
                   help="weight of the quality term at labelled failures (the negative "
                        "rectangles) for --loss weighted, relative to unlabelled pixels "
                        f"(default {DEFAULT_NEG_WEIGHT:g}: no extra weight)")
    p.add_argument("--balance-images", action="store_true",
                   help="weighted loss: weigh each image's positives by the batch's mean "
                        "positive area over its own (clamped to [1/4, 4])")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--holdout", choices=["per-category", "fraction", "init"], default=None,
                   help="held-out objects: init (the objects --init's checkpoint held out; "
                        "the default with an --init that records them), per-category "
                        "(default when the index gives categories) or fraction (default "
                        "otherwise)")
    p.add_argument("--per-category", type=int, default=1,
                   help="objects held out per category with --holdout per-category (default 1)")
    p.add_argument("--val-fraction", type=float, default=0.1,
                   help="fraction of objects held out with --holdout fraction (default 0.1)")
    p.add_argument("--object-map", type=Path, help="file of '<stem> <object id>' lines")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    p.add_argument("--no-augment", action="store_true",
                   help="no random shift, flip and rotation (zoom for non-square images)")
    p.add_argument("--repeat", action="append", default=[], metavar="DIR=K",
                   help="show the training images of --data DIR K times per epoch (repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    a = p.parse_args(argv)
    try:
        a.repeat = parse_repeats(a.repeat, a.data)
    except ValueError as e:
        p.error(str(e))
    if a.epochs < 1:
        p.error("--epochs must be at least 1")
    if a.input_size is not None and (a.input_size < 16 or a.input_size % 4):
        p.error(f"--input-size must be a multiple of 4 and at least 16, got {a.input_size}")
    if a.batch_size < 1:
        p.error("--batch-size must be at least 1")
    if not a.lr > 0:
        p.error("--lr must be positive")
    if not a.pos_weight > 0:
        p.error("--pos-weight must be positive")
    if not a.neg_weight > 0:
        p.error("--neg-weight must be positive")
    if not a.width_weight > 0:
        p.error("--width-weight must be positive")
    if not 0 <= a.val_fraction < 1:
        p.error("--val-fraction must be in [0, 1)")
    if a.per_category < 0:
        p.error("--per-category must be non-negative")
    if a.threads < 1:
        p.error("--threads must be at least 1")
    return a


def parse_repeats(specs: list[str], data: list[Path]) -> dict[Path, int]:
    """``--repeat DIR=K`` arguments as {directory: K}; each DIR must be one of ``data``."""
    out: dict[Path, int] = {}
    for spec in specs:
        d, sep, k = spec.rpartition("=")
        if not sep or not d:
            raise ValueError(f"--repeat {spec!r}: expected DIR=K")
        try:
            times = int(k)
        except ValueError:
            raise ValueError(f"--repeat {spec!r}: K must be a whole number") from None
        if times < 1:
            raise ValueError(f"--repeat {spec!r}: K must be at least 1")
        root = Path(d)
        if root not in data:
            raise ValueError(f"--repeat {spec!r}: {d} is not one of --data "
                             f"{[str(x) for x in data]}")
        if root in out:
            raise ValueError(f"--repeat names {d} twice")
        out[root] = times
    return out


def repeated(samples: list[Sample], repeats: dict[Path, int]) -> list[Sample]:
    """``samples`` with those under a directory of ``repeats`` shown K times (in place: a
    sample's copies follow it, so the order and thus the seeded batches stay reproducible)."""
    if not repeats:
        return samples
    out: list[Sample] = []
    for s in samples:
        k = next((k for d, k in repeats.items() if s.rgb_path.is_relative_to(d)), 1)
        out.extend([s] * k)
    return out


def held_out_by(start: tuple | None) -> list[str] | None:
    """The objects a loaded checkpoint (``load_checkpoint``'s pair) held out, if it says."""
    if start is None:
        return None
    return ((start[1].get("metrics") or {}).get("heldout") or {}).get("objects") or None


def split_as_init(samples: list[Sample], start: tuple | None, init: Path | None
                  ) -> tuple[list[Sample], list[Sample]]:
    """(train, held-out) with the objects the ``--init`` checkpoint held out held out again, so
    a fine-tune never trains on what its starting point was scored on."""
    if start is None:
        raise DatasetError("--holdout init needs --init CKPT")
    held = set(held_out_by(start) or ())
    if not held:
        raise DatasetError(f"--init {init} records no held-out objects: choose --holdout "
                           f"per-category or fraction")
    return ([s for s in samples if s.object_id not in held],
            [s for s in samples if s.object_id in held])


def run(a: argparse.Namespace) -> dict:
    torch.set_num_threads(a.threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(a.seed)
    log = sys.stderr
    data_txt = ", ".join(str(d) for d in a.data)
    object_map = read_object_map(a.object_map) if a.object_map else None
    samples, jaw_fraction = find_samples_in(a.data, object_map)
    has_categories = all(s.category is not None for s in samples)
    start = load_checkpoint(a.init) if a.init is not None else None
    holdout = a.holdout or ("init" if held_out_by(start) else
                            "per-category" if has_categories else "fraction")
    if holdout == "init":
        train_s, held_s = split_as_init(samples, start, a.init)
    elif holdout == "per-category":
        if not has_categories:
            raise DatasetError(f"{data_txt}: --holdout per-category needs categories from an lgdm "
                               f"index.json (format lgdm.grasp.v2); use --holdout fraction")
        train_s, held_s = split_held_out_instances(samples, a.per_category, a.seed)
    else:
        train_s, held_s = split_by_object(samples, a.val_fraction, a.seed)
    distinct = len(train_s)
    train_s = repeated(train_s, a.repeat)
    config = dataclasses.replace(ModelConfig.preset(a.config), jaw_side_fraction=jaw_fraction)
    if start is not None:
        config = dataclasses.replace(config, input_size=start[0].config.input_size)
    if a.input_size is not None:
        config = dataclasses.replace(config, input_size=a.input_size)
    model = GraspAutoencoder(config)
    init = None
    if start is not None:
        start, _ = start
        if dataclasses.replace(start.config, jaw_side_fraction=None,
                               input_size=config.input_size) != dataclasses.replace(
                config, jaw_side_fraction=None):
            raise DatasetError(f"--init {a.init} is a {start.config.name!r} network, not "
                               f"--config {a.config}")
        model.load_state_dict(start.state_dict())
        init = {"file": a.init.name, "sha256": hashlib.sha256(a.init.read_bytes()).hexdigest()}
        print(f"starting from {a.init} (sha256 {init['sha256'][:16]}…)", file=log)
        if config.input_size != start.config.input_size:
            rescale_widths(model, config.input_size / start.config.input_size)
            print(f"input {start.config.input_size} -> {config.input_size} px: width head "
                  f"scaled by {config.input_size / start.config.input_size:g}", file=log)
    train_objects = sorted({s.object_id for s in train_s})
    held_objects = sorted({s.object_id for s in held_s})
    jaw_txt = (f"decoded jaw = {jaw_fraction:.4f} x side "
               f"({jaw_fraction * config.input_size:.2f} px)" if jaw_fraction is not None
               else "decoded jaw = opening / 2 (no lgdm index)")
    print(f"config {config.name}: {parameter_count(model):,} parameters, input "
          f"{config.input_size}x{config.input_size}; {jaw_txt}", file=log)
    print(f"held out ({holdout}): {len(held_s)} images of {len(held_objects)} objects "
          f"{held_objects}; training: {len(train_s)} images"
          + (f" ({distinct} distinct, --repeat)" if len(train_s) != distinct else "")
          + f" of {len(train_objects)} objects",
          file=log)
    print(f"optimizer {a.optimizer} lr {a.lr:g}, loss {a.loss}"
          + (f" (positives x{a.pos_weight:g}"
             + (f", failures x{a.neg_weight:g}" if a.neg_weight != 1 else "")
             + (f", width term x{a.width_weight:g}" if a.width_weight != 1 else "")
             + (", images balanced" if a.balance_images else "") + ")"
             if a.loss == "weighted" else "")
          + f", batch {a.batch_size}, augment {'off' if a.no_augment else 'on'}", file=log)
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

    hist = train_model(model, train_ds, a.epochs, a.batch_size, a.lr, a.seed, progress,
                       loss=a.loss, pos_weight=a.pos_weight, optimizer=a.optimizer,
                       neg_weight=a.neg_weight, width_weight=a.width_weight,
                       balance_images=a.balance_images)
    s_per_img = hist.seconds / max(hist.images, 1)
    print(f"trained {a.epochs} epochs in {hist.seconds:.1f} s ({s_per_img:.3f} s per image, "
          f"{a.threads} threads); final epoch loss {hist.epoch_loss[-1]:.4f}", file=log)

    heldout = None
    if held_s:
        ds = GraspDataset(held_s, config.input_size, augment=False)
        t0 = time.perf_counter()
        heldout = evaluate_model(model, ds, jaw_side_fraction=jaw_fraction)
        heldout["objects"] = held_objects
        print(f"held-out objects, final epoch {a.epochs}: {format_result(heldout)} "
              f"[{time.perf_counter() - t0:.1f} s]", file=log)
    else:
        print("no held-out objects (too few objects, --val-fraction 0 or --per-category 0): "
              "no evaluation", file=log)
    metrics = {
        "training": {
            "data": [str(d) for d in a.data],
            "init": init,
            "epochs": a.epochs,
            "batch_size": a.batch_size,
            "lr": a.lr,
            "optimizer": a.optimizer,
            "loss": a.loss,
            "pos_weight": a.pos_weight if a.loss == "weighted" else None,
            "neg_weight": a.neg_weight if a.loss == "weighted" else None,
            "width_weight": a.width_weight if a.loss == "weighted" else None,
            "balance_images": a.balance_images if a.loss == "weighted" else None,
            "seed": a.seed,
            "holdout": holdout,
            "per_category": a.per_category if holdout == "per-category" else None,
            "val_fraction": a.val_fraction if holdout == "fraction" else None,
            "jaw_side_fraction": jaw_fraction,
            "augment": not a.no_augment,
            "threads": a.threads,
            "train_objects": train_objects,
            "train_images": len(train_s),
            "repeat": {str(d): k for d, k in a.repeat.items()} or None,
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
    except (ValueError, FileNotFoundError) as e:  # DatasetError is a ValueError
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
