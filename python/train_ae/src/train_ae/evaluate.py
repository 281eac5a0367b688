"""Score a checkpoint with the rectangle metric.

    python -m train_ae.evaluate --data DIR --ckpt CKPT [--all] [--object-map FILE] [--threads 2]

By default only the objects the checkpoint held out of training are scored (they must exist in
DIR); ``--all`` scores every image in DIR (e.g. a different dataset). Prints n, the accuracy
and a 95 % Wilson confidence interval. Decoded jaws follow the checkpoint's
``jaw_side_fraction`` (the training data's finger width), or opening / 2 when it has none.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from .checkpoint import load_checkpoint
from .data import DatasetError, GraspDataset, find_samples, read_grasp_index, read_object_map
from .progress import ProgressBar
from .training import evaluate_model, format_result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.evaluate", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path)
    p.add_argument("--ckpt", required=True, type=Path)
    p.add_argument("--all", action="store_true", help="score every image, not only held-out "
                   "objects")
    p.add_argument("--object-map", type=Path, help="file of '<stem> <object id>' lines")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--json", action="store_true", help="also print the result as JSON on stdout")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    try:
        model, ckpt = load_checkpoint(a.ckpt)
        object_map = read_object_map(a.object_map) if a.object_map else None
        samples = find_samples(a.data, object_map)
        index = read_grasp_index(a.data)
        if not a.all:
            held = ((ckpt.get("metrics") or {}).get("heldout") or {}).get("objects")
            if not held:
                raise DatasetError(f"{a.ckpt} records no held-out objects; use --all")
            samples = [s for s in samples if s.object_id in set(held)]
            if not samples:
                raise DatasetError(f"none of the held-out objects {held} is in {a.data}; "
                                   f"use --all to score every image")
    except (DatasetError, FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    jaw = model.config.jaw_side_fraction
    data_jaw = index.jaw_side_fraction if index is not None else None
    if (jaw is None) != (data_jaw is None) or (
            jaw is not None and abs(jaw - data_jaw) > 1e-6 * jaw):
        print(f"warning: the checkpoint decodes jaws with jaw_side_fraction {jaw}, the index of "
              f"{a.data} says {data_jaw}; using the checkpoint's", file=sys.stderr)
    ds = GraspDataset(samples, model.config.input_size, augment=False)
    bar = ProgressBar(len(ds), "evaluate", enabled=not a.quiet)
    result = evaluate_model(model, ds, progress=lambda done, total: bar.update(done - bar.done),
                            jaw_side_fraction=jaw)
    bar.close()
    objects = sorted({s.object_id for s in samples})
    result["objects"] = objects
    result["jaw_side_fraction"] = jaw
    print(f"config {model.config.name}, {len(objects)} objects: {format_result(result)}",
          file=sys.stderr)
    if a.json:
        print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
