"""Regenerate the shipped default checkpoint (``weights/cpu.pt``) from scratch.

    python -m train_ae.make_default --lgdm PATH/TO/lgdm --work DIR [--out CKPT]
        [--preset paper] [--images 2000] [--epochs 50] [--seed 0] [--threads 1] [--skip-data]

Two steps, each printed as the equivalent shell command before it runs:

1. ``lgdm gen-dataset --preset P --frames 1 --grasp-images N --seed S --out DIR/data
   --progress none``: object-centred 224-px crops of 0.22 m of table with an index.json naming
   each image's object and category (``--frames 1``: the grasp images do not depend on the
   number of views per sequence, and one view keeps the MCAP output small);
2. ``python -m train_ae.train --data DIR/data/grasp --config cpu --epochs E --seed S
   --threads T --holdout per-category --out CKPT``: holds out one whole instance per category
   and prints the final epoch's rectangle metric on them.

The defaults are the settings of the shipped checkpoint (see the package README for its
figures). Same lgdm build, seed and thread count -> the same checkpoint bytes.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
from pathlib import Path

from . import train
from .bridge import DEFAULT_CHECKPOINT

DEFAULTS = {
    "preset": "paper",
    "images": 2000,
    "epochs": 50,
    "seed": 0,
    "threads": 1,
}
"""Settings of the shipped checkpoint."""


def commands(lgdm: Path, work: Path, out: Path, preset: str, images: int, epochs: int,
             seed: int, threads: int) -> tuple[list[str], list[str]]:
    """(gen-dataset argv, ``train_ae.train`` argv) of the two steps."""
    data = work / "data"
    gen = [str(lgdm), "gen-dataset", "--preset", preset, "--frames", "1",
           "--grasp-images", str(images), "--seed", str(seed), "--out", str(data),
           "--progress", "none"]
    train_argv = ["--data", str(data / "grasp"), "--config", "cpu", "--epochs", str(epochs),
                  "--seed", str(seed), "--threads", str(threads), "--holdout", "per-category",
                  "--out", str(out)]
    return gen, train_argv


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.make_default", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lgdm", required=True, type=Path, help="the lgdm binary (release build)")
    p.add_argument("--work", required=True, type=Path, help="directory for the data")
    p.add_argument("--out", type=Path, default=DEFAULT_CHECKPOINT,
                   help=f"checkpoint to write (default: {DEFAULT_CHECKPOINT})")
    p.add_argument("--preset", choices=["paper", "small"], default=DEFAULTS["preset"])
    p.add_argument("--images", type=int, default=DEFAULTS["images"])
    p.add_argument("--epochs", type=int, default=DEFAULTS["epochs"])
    p.add_argument("--seed", type=int, default=DEFAULTS["seed"])
    p.add_argument("--threads", type=int, default=DEFAULTS["threads"])
    p.add_argument("--skip-data", action="store_true",
                   help="reuse DIR/data if gen-dataset already wrote it")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    gen, train_argv = commands(a.lgdm, a.work, a.out, a.preset, a.images, a.epochs, a.seed,
                               a.threads)
    index = a.work / "data" / "grasp" / "index.json"
    if a.skip_data and index.is_file():
        print(f"# step 1 skipped: {index} exists (--skip-data)", file=sys.stderr)
    else:
        print("# step 1: the grasp images\n$ " + shlex.join(gen), file=sys.stderr)
        a.work.mkdir(parents=True, exist_ok=True)
        r = subprocess.run(gen, check=False)
        if r.returncode != 0:
            print(f"error: gen-dataset exited with {r.returncode}", file=sys.stderr)
            return 2
    if a.quiet:
        train_argv.append("--quiet")
    print("# step 2: training and the held-out evaluation\n$ python -m train_ae.train "
          + shlex.join(train_argv), file=sys.stderr)
    return train.main(train_argv)


if __name__ == "__main__":
    raise SystemExit(main())
