"""Regenerate the shipped default checkpoint (``weights/cpu.pt``) from scratch.

    python -m train_ae.make_default --lgdm PATH/TO/lgdm --work DIR [--out CKPT]
        [--preset paper] [--images 1000] [--epochs N] [--seed 0] [--threads 1]
        [--val-fraction 0.1]

Three steps, each also printed as the equivalent shell command:

1. ``lgdm gen-dataset --preset P --frames 1 --grasp-images N --seed S --out DIR/data``
   (``--frames 1``: the grasp images do not depend on the number of views per sequence, and
   one view keeps the MCAP output small);
2. an object map ``DIR/objects.txt`` (``pcdNNNN <object>`` per image, from
   ``DIR/data/grasp/index.json``), so held-out objects are whole object instances;
3. ``python -m train_ae.train --data DIR/data/grasp --object-map DIR/objects.txt --config cpu
   ...`` writing the checkpoint; it holds out whole objects and prints the final epoch's
   rectangle metric on them.

The defaults are the settings of the shipped checkpoint (see the package README for its
figures). Same lgdm build, seed and thread count -> the same checkpoint bytes.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path

from . import train
from .bridge import DEFAULT_CHECKPOINT

DEFAULTS = {
    "preset": "paper",
    "images": 1000,
    "epochs": 20,
    "seed": 0,
    "threads": 1,
    "val_fraction": 0.1,
}
"""Settings of the shipped checkpoint."""


def write_object_map(index_json: str | Path, out: str | Path) -> int:
    """``pcdNNNN <object>`` lines from a ``gen-dataset`` grasp index; returns the line count."""
    entries = json.loads(Path(index_json).read_text())
    lines = []
    for e in entries:
        stem = Path(e["prefix"]).name
        obj = str(e["object"])
        if not stem.startswith("pcd") or not obj or any(c.isspace() for c in obj):
            raise ValueError(f"{index_json}: unusable entry prefix={e['prefix']!r} "
                             f"object={obj!r}")
        lines.append(f"{stem} {obj}\n")
    out = Path(out)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text("".join(lines))
    tmp.replace(out)
    return len(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.make_default", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lgdm", required=True, type=Path, help="the lgdm binary (release build)")
    p.add_argument("--work", required=True, type=Path, help="directory for data and map")
    p.add_argument("--out", type=Path, default=DEFAULT_CHECKPOINT,
                   help=f"checkpoint to write (default: {DEFAULT_CHECKPOINT})")
    p.add_argument("--preset", choices=["paper", "small"], default=DEFAULTS["preset"])
    p.add_argument("--images", type=int, default=DEFAULTS["images"])
    p.add_argument("--epochs", type=int, default=DEFAULTS["epochs"])
    p.add_argument("--seed", type=int, default=DEFAULTS["seed"])
    p.add_argument("--threads", type=int, default=DEFAULTS["threads"])
    p.add_argument("--val-fraction", type=float, default=DEFAULTS["val_fraction"])
    p.add_argument("--skip-data", action="store_true",
                   help="reuse DIR/data if gen-dataset already wrote it")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    data = a.work / "data"
    index = data / "grasp" / "index.json"
    gen = [str(a.lgdm), "gen-dataset", "--preset", a.preset, "--frames", "1",
           "--grasp-images", str(a.images), "--seed", str(a.seed), "--out", str(data),
           "--progress", "none"]
    if not (a.skip_data and index.is_file()):
        print("$ " + shlex.join(gen), file=sys.stderr)
        a.work.mkdir(parents=True, exist_ok=True)
        r = subprocess.run(gen, check=False)
        if r.returncode != 0:
            print(f"error: gen-dataset exited with {r.returncode}", file=sys.stderr)
            return 2
    object_map = a.work / "objects.txt"
    n = write_object_map(index, object_map)
    print(f"wrote {object_map} ({n} images)", file=sys.stderr)
    train_argv = ["--data", str(data / "grasp"), "--object-map", str(object_map),
                  "--config", "cpu", "--epochs", str(a.epochs), "--seed", str(a.seed),
                  "--threads", str(a.threads), "--val-fraction", str(a.val_fraction),
                  "--out", str(a.out)]
    if a.quiet:
        train_argv.append("--quiet")
    print("$ python -m train_ae.train " + shlex.join(train_argv), file=sys.stderr)
    return train.main(train_argv)


if __name__ == "__main__":
    raise SystemExit(main())
