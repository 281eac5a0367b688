"""Train the grasp network on a GPU from packs, within a wall-clock budget, and optionally
distil it into the ``cpu`` configuration.

    python -m train_ae.gpu --pack FILE [--pack FILE ...] --config paper --minutes 7 --out DIR
        [--distill cpu] [--distill-init CKPT] [--distill-fraction 0.35] [--distill-weight 10]
        [--init CKPT] [--batch-size 128] [--distill-batch-size 256] [--lr 2e-3]
        [--distill-lr 1e-3] [--warmup-steps 200] [--pos-weight 10] [--neg-weight 10]
        [--width-weight 1] [--balance-images] [--seed 0]
        [--holdout per-category|fraction] [--holdout-from CKPT] [--per-category 1]
        [--val-fraction 0.1] [--repeat DATASET=K ...] [--save-every 60] [--workers N]
        [--commit SHA | --commit-file FILE] [--max-steps N] [--device cuda|cpu]

``--minutes`` is the budget of the whole command from its start — loading, label maps,
training, distillation, both held-out evaluations and the files —; training stops early
enough for the rest (each phase's learning rate is a cosine over its own time, after a linear
warm-up). Whole objects are held out as ``train_ae.train`` holds them out (one instance per
category, seeded; ``--holdout-from CKPT``: the objects a checkpoint held out, e.g. the shipped
``weights/cpu.pt``'s, so a student started from it with ``--distill-init`` never saw them) and
scored with the rectangle metric at the end, on the final networks.

Writes into ``--out``: ``<config>.pt`` (the trained network), ``<distill>-distilled.pt`` (the
student), both ordinary train_ae checkpoints (``bridge.load``, ``train_ae.evaluate --ckpt``),
saved atomically every ``--save-every`` seconds and at the end, so a killed run still leaves
the last one; and ``record.json``: packs (file, sha256, manifest), settings, seeds, split,
per phase steps, epochs, images/s, wall time, loss, held-out result, and the machine (GPU,
torch, CUDA), the git commit given, the outputs' sha256.

The loss is ``training.grasp_loss`` (weighted by default). The student's loss is that loss on
its own targets plus ``--distill-weight`` x the paper loss (plain smooth-L1 means) between its
maps and the teacher's (area-averaged to its resolution, widths scaled). On CUDA: bf16
autocast, channels-last, cuDNN autotuning (not bit-reproducible); on the CPU (tests) float32.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import os
import platform
import sys
import time
import traceback
from pathlib import Path

_T0 = time.monotonic()

import numpy as np  # noqa: E402
import torch  # noqa: E402

from .. import train as train_cli  # noqa: E402
from ..checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from ..data import DatasetError, split_by_object, split_held_out_instances  # noqa: E402
from ..model import GraspAutoencoder, GraspMaps, ModelConfig, parameter_count  # noqa: E402
from ..pack import PackedGraspDataset, PackError, dataset_of, read_pack  # noqa: E402
from ..training import (  # noqa: E402
    DEFAULT_POS_WEIGHT,
    DEFAULT_WIDTH_WEIGHT,
    evaluate_model,
    format_result,
    grasp_loss,
)
from . import DeviceImages, OnDevice, cpu_state, default_workers, finite_state, teacher_targets  # noqa: E402

FORMAT = "lgdm.train_ae.gpu-record.v1"
EVAL_S_PER_IMAGE_112 = 0.015
"""Budgeted held-out evaluation time per image at 112 px (x4 at 224): loading, inference,
decoding on the CPU; measured on the teacher's evaluation for the student's."""
SAFETY_S = 10.0


def log(msg: str) -> None:
    print(f"[{time.monotonic() - _T0:7.1f} s] {msg}", flush=True)


def _args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m train_ae.gpu", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pack", required=True, type=Path, action="append", metavar="FILE")
    p.add_argument("--config", choices=["cpu", "paper"], default="paper")
    p.add_argument("--minutes", type=float, required=True,
                   help="wall-clock budget of the whole command")
    p.add_argument("--out", required=True, type=Path, help="directory for checkpoints + record")
    p.add_argument("--init", type=Path, help="start the network from this checkpoint")
    p.add_argument("--distill", choices=["cpu", "paper"], help="distil into this config")
    p.add_argument("--distill-init", type=Path, metavar="CKPT",
                   help="start the student from this checkpoint (e.g. the shipped cpu.pt)")
    p.add_argument("--distill-fraction", type=float, default=0.35,
                   help="share of the training time given to the distillation")
    p.add_argument("--distill-weight", type=float, default=10.0,
                   help="weight of the teacher term in the student's loss")
    p.add_argument("--batch-size", type=int, default=128)
    p.add_argument("--distill-batch-size", type=int, default=256)
    p.add_argument("--lr", type=float, default=2e-3, help="peak Adam learning rate")
    p.add_argument("--distill-lr", type=float, default=1e-3)
    p.add_argument("--lr-floor", type=float, default=0.05,
                   help="the cosine ends at this fraction of the peak")
    p.add_argument("--warmup-steps", type=int, default=200)
    p.add_argument("--pos-weight", type=float, default=DEFAULT_POS_WEIGHT)
    p.add_argument("--neg-weight", type=float, default=10.0,
                   help="weight of labelled failures in the quality term (make_default's 10)")
    p.add_argument("--width-weight", type=float, default=DEFAULT_WIDTH_WEIGHT)
    p.add_argument("--balance-images", action="store_true")
    p.add_argument("--no-augment", action="store_true")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--holdout", choices=["per-category", "fraction"], default="per-category")
    p.add_argument("--holdout-from", type=Path, metavar="CKPT",
                   help="hold out the objects this checkpoint held out")
    p.add_argument("--per-category", type=int, default=1)
    p.add_argument("--val-fraction", type=float, default=0.1)
    p.add_argument("--repeat", action="append", default=[], metavar="DATASET=K",
                   help="show a pack dataset's training images K times per epoch")
    p.add_argument("--save-every", type=float, default=60.0, help="seconds between saves")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the label maps (default: the CPUs)")
    p.add_argument("--commit", help="git commit of the code, for the record")
    p.add_argument("--commit-file", type=Path, help="a file holding the git commit")
    p.add_argument("--max-steps", type=int, help="stop each phase after this many steps")
    p.add_argument("--device", help="cuda or cpu (default: cuda when available)")
    a = p.parse_args(argv)
    if not a.minutes > 0:
        p.error("--minutes must be positive")
    if a.batch_size < 1 or a.distill_batch_size < 1:
        p.error("batch sizes must be at least 1")
    if not (a.lr > 0 and a.distill_lr > 0 and 0 <= a.lr_floor <= 1):
        p.error("learning rates must be positive, --lr-floor in [0, 1]")
    if not 0 < a.distill_fraction < 1:
        p.error("--distill-fraction must be in (0, 1)")
    if not (a.pos_weight > 0 and a.neg_weight > 0 and a.width_weight > 0):
        p.error("loss weights must be positive")
    if a.distill_init and not a.distill:
        p.error("--distill-init needs --distill")
    repeats = {}
    for spec in a.repeat:
        name, sep, k = spec.rpartition("=")
        if not sep or not name or not k.isdigit() or int(k) < 1:
            p.error(f"--repeat {spec!r}: expected DATASET=K with K >= 1")
        repeats[name] = int(k)
    a.repeat = repeats
    return a


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _write_json(path: Path, obj: dict) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(obj, indent=1, default=str) + "\n")
    os.replace(tmp, path)


def _commit(a: argparse.Namespace) -> str | None:
    if a.commit:
        return a.commit
    if a.commit_file is not None and a.commit_file.is_file():
        return a.commit_file.read_text().strip() or None
    return None


def _machine(device: torch.device) -> dict:
    out = {"device": str(device), "torch": torch.__version__, "numpy": np.__version__,
           "python": platform.python_version(), "cpus": os.cpu_count(),
           "host": platform.node()}
    if device.type == "cuda":
        props = torch.cuda.get_device_properties(device)
        out.update(gpu=torch.cuda.get_device_name(device), cuda=torch.version.cuda,
                   cudnn=torch.backends.cudnn.version(),
                   gpu_memory_gib=round(props.total_memory / 2**30, 1))
    return out


class Phase:
    """One network trained on the device until a deadline: its optimiser, counters, saves."""

    def __init__(self, name: str, model: GraspAutoencoder, path: Path, lr: float,
                 batch_size: int, start: float, deadline: float, a: argparse.Namespace,
                 metrics_base: dict):
        self.name, self.model, self.path = name, model, path
        self.lr, self.batch_size = lr, batch_size
        self.start, self.deadline = start, deadline
        self.a = a
        self.metrics_base = metrics_base
        self.opt = torch.optim.Adam(model.parameters(), lr=lr)
        self.steps = self.images = 0
        self.epoch_loss: list[float] = []
        self.saved_at = -1.0
        self.good_state = cpu_state(model)
        self.restarts = 0
        self.stopped = "budget"

    def lr_at(self, now: float) -> float:
        warm = min(1.0, (self.steps + 1) / max(self.a.warmup_steps, 1))
        frac = min(max((now - self.start) / max(self.deadline - self.start, 1e-9), 0.0), 1.0)
        floor = self.a.lr_floor
        return self.lr * warm * (floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * frac)))

    def summary(self, n_train: int) -> dict:
        wall = max(time.monotonic() - self.start, 1e-9)
        return {"steps": self.steps, "images": self.images,
                "epochs": round(self.images / max(n_train, 1), 3),
                "wall_s": round(wall, 1), "images_per_s": round(self.images / wall, 1),
                "batch_size": self.batch_size, "lr": self.lr, "stopped": self.stopped,
                "restarts_after_nonfinite_loss": self.restarts,
                "epoch_loss": [round(v, 5) for v in self.epoch_loss]}

    def save(self, metrics: dict) -> bool:
        state = cpu_state(self.model)
        if not finite_state(state):
            log(f"{self.name}: weights not finite; keeping the last saved checkpoint")
            return False
        cpu_model = GraspAutoencoder(self.model.config)
        cpu_model.load_state_dict(state)
        save_checkpoint(self.path, cpu_model, metrics)
        self.good_state = state
        self.saved_at = time.monotonic()
        return True


def _train(phase: Phase, data: DeviceImages, train_idx: np.ndarray, size: int,
           a: argparse.Namespace, device: torch.device, on_save,
           teacher: GraspAutoencoder | None = None, teacher_size: int | None = None) -> None:
    model = phase.model
    model.train()
    cuda = device.type == "cuda"
    fmt = torch.channels_last if cuda else torch.contiguous_format
    sizes = [size] if teacher is None else sorted({size, teacher_size})
    b = min(phase.batch_size, len(train_idx))
    epoch = 0
    last_log = time.monotonic()
    loss_sum = torch.zeros((), device=device)
    loss_n = 0
    while True:
        rot, flip, shift = data.draw(len(train_idx), a.seed, epoch, augment=not a.no_augment)
        order = np.random.default_rng([a.seed, epoch]).permutation(len(train_idx))
        idx_all = torch.from_numpy(train_idx[order]).to(device)
        rot_all = torch.from_numpy(rot).to(device)
        flip_all = torch.from_numpy(flip).to(device)
        shift_all = torch.from_numpy(shift).to(device)
        ep_sum = torch.zeros((), device=device)
        ep_n = 0
        for s in range(0, len(train_idx) - b + 1, b):
            now = time.monotonic()
            if now >= phase.deadline:
                break
            if a.max_steps is not None and phase.steps >= a.max_steps:
                phase.stopped = "max_steps"
                break
            lr = phase.lr_at(now)
            for g in phase.opt.param_groups:
                g["lr"] = lr
            sl = slice(s, s + b)
            batches = data.batch(idx_all[sl], rot_all[sl], flip_all[sl], shift_all[sl], sizes,
                                 [size])
            x, y = batches[size]
            with torch.autocast(device.type, dtype=torch.bfloat16, enabled=cuda):
                maps = model(x.contiguous(memory_format=fmt))
            maps = GraspMaps(*(m.float() for m in maps))
            with torch.device(device):  # grasp_loss makes a tensor without a device
                loss = grasp_loss(maps, y, "weighted", a.pos_weight, a.neg_weight,
                                  a.width_weight, a.balance_images)
                if teacher is not None:
                    xt = batches[teacher_size][0]
                    with torch.no_grad(), torch.autocast(device.type, dtype=torch.bfloat16,
                                                         enabled=cuda):
                        soft = teacher_targets(teacher(xt.contiguous(memory_format=fmt)), size)
                    loss = loss + a.distill_weight * grasp_loss(maps, soft, "paper")
            phase.opt.zero_grad(set_to_none=True)
            loss.backward()
            phase.opt.step()
            phase.steps += 1
            phase.images += b
            loss_sum += loss.detach()
            ep_sum += loss.detach()
            loss_n += 1
            ep_n += 1
            now = time.monotonic()
            if now - last_log >= 10 or phase.steps == 1:
                mean = float(loss_sum) / max(loss_n, 1)
                if not math.isfinite(mean):
                    phase.restarts += 1
                    phase.lr *= 0.5
                    log(f"{phase.name}: non-finite loss; back to the last saved weights, peak "
                        f"lr halved to {phase.lr:g}")
                    model.load_state_dict(phase.good_state)
                    phase.opt = torch.optim.Adam(model.parameters(), lr=phase.lr)
                    if phase.restarts > 3:
                        phase.stopped = "nonfinite"
                        return
                else:
                    rate = phase.images / max(now - phase.start, 1e-9)
                    log(f"{phase.name}: step {phase.steps}, epoch "
                        f"{phase.images / len(train_idx):.2f}, loss {mean:.4f}, lr {lr:.2e}, "
                        f"{rate:.0f} img/s, {phase.deadline - now:.0f} s left")
                loss_sum.zero_()
                loss_n = 0
                last_log = now
            if now - phase.saved_at >= a.save_every:
                on_save()
        else:
            if ep_n:
                phase.epoch_loss.append(float(ep_sum) / ep_n)
            epoch += 1
            continue
        if ep_n:
            phase.epoch_loss.append(float(ep_sum) / ep_n)
        return


def _evaluate(model: GraspAutoencoder, packs, held_items, device, jaw) -> dict | None:
    """The rectangle metric on the held-out images; a failure is logged and recorded (the
    checkpoint is still written), not raised."""
    if not held_items:
        return None
    ds = PackedGraspDataset(packs, held_items, model.config.input_size)
    objects = sorted({s.object_id for s in ds.samples})
    try:
        result = evaluate_model(OnDevice(model, device), ds, batch_size=64,
                                jaw_side_fraction=jaw)
    except Exception as e:  # one run on a lent machine: keep the weights whatever happens
        log(f"held-out evaluation failed: {e!r}\n{traceback.format_exc()}")
        return {"objects": objects, "error": repr(e)}
    result["objects"] = objects
    return result


def run(a: argparse.Namespace) -> dict:
    budget_end = _T0 + 60.0 * a.minutes
    device = torch.device(a.device or ("cuda" if torch.cuda.is_available() else "cpu"))
    a.out.mkdir(parents=True, exist_ok=True)
    record_path = a.out / "record.json"
    record: dict = {"format": FORMAT, "argv": sys.argv[1:], "commit": _commit(a),
                    "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                    "minutes": a.minutes, "seed": a.seed}
    log(f"device {device}; torch {torch.__version__}; budget {a.minutes:g} min")

    packs = []
    record["packs"] = []
    for path in a.pack:
        pk = read_pack(path)
        packs.append(pk)
        record["packs"].append({"file": path.name, "bytes": path.stat().st_size,
                                "sha256": _sha256(path), "manifest": pk.manifest})
        log(f"{path}: {len(pk)} images at {pk.size} px from "
            f"{', '.join(d['name'] for d in pk.manifest['datasets'])}")
    jaws = {p.jaw_side_fraction for p in packs}
    if len(jaws) != 1 or (None not in jaws and max(jaws) - min(jaws) > 1e-6 * max(jaws)):
        raise DatasetError(f"packs made for different jaws: {sorted(jaws, key=str)}")
    jaw = packs[0].jaw_side_fraction
    names = [d["name"] for p in packs for d in p.manifest["datasets"]]
    if len(set(names)) != len(names):
        raise DatasetError(f"a dataset name appears in two packs: {names}")
    unknown = sorted(set(a.repeat) - set(names))
    if unknown:
        raise DatasetError(f"--repeat names {unknown}, not datasets of the packs {names}")

    items = [(p, i) for p, pk in enumerate(packs) for i in range(len(pk))]
    samples = [packs[p].samples[i] for p, i in items]
    if a.holdout_from is not None:
        start = load_checkpoint(a.holdout_from)
        train_s, held_s = train_cli.split_as_init(samples, start, a.holdout_from)
        holdout = f"from {a.holdout_from.name}"
    elif a.holdout == "per-category":
        train_s, held_s = split_held_out_instances(samples, a.per_category, a.seed)
        holdout = "per-category"
    else:
        train_s, held_s = split_by_object(samples, a.val_fraction, a.seed)
        holdout = "fraction"
    held_ids = {id(s) for s in held_s}
    train_idx, held_items = [], []
    for k, s in enumerate(samples):
        if id(s) in held_ids:
            held_items.append(items[k])
        else:
            train_idx.extend([k] * a.repeat.get(dataset_of(s), 1))
    train_idx = np.asarray(train_idx, np.int64)
    held_objects = sorted({s.object_id for s in held_s})
    train_objects = sorted({s.object_id for s in train_s})
    log(f"held out ({holdout}): {len(held_items)} images of {len(held_objects)} objects "
        f"{held_objects}; training {len(train_idx)} images of {len(train_objects)} objects")
    if not len(train_idx):
        raise DatasetError("no training images left after the split")
    record["split"] = {"holdout": holdout, "per_category": a.per_category,
                       "held_out_objects": held_objects, "held_out_images": len(held_items),
                       "train_objects": len(train_objects), "train_images": len(train_idx),
                       "repeat": a.repeat or None}

    config = dataclasses.replace(ModelConfig.preset(a.config), jaw_side_fraction=jaw)
    student_config = None
    if a.distill:
        student_config = dataclasses.replace(ModelConfig.preset(a.distill),
                                             jaw_side_fraction=jaw)
    init = load_checkpoint(a.init)[0] if a.init else None
    student_init = load_checkpoint(a.distill_init)[0] if a.distill_init else None
    for m, c, flag in ((init, config, "--init"), (student_init, student_config,
                                                  "--distill-init")):
        if m is not None and dataclasses.replace(m.config, jaw_side_fraction=None) != \
                dataclasses.replace(c, jaw_side_fraction=None):
            raise DatasetError(f"{flag} is a {m.config.name!r} network of "
                               f"{m.config.input_size} px, not {c.name!r}")
    sizes = [config.input_size] + ([student_config.input_size] if student_config else [])
    workers = a.workers or default_workers()
    data = DeviceImages(packs, device, sizes, workers, log)
    log(f"on {device}: {len(data)} images and label maps ready (workers {workers})")
    record["machine"] = _machine(device)
    if device.type == "cuda":
        torch.backends.cudnn.benchmark = True
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
        torch.set_num_threads(max(1, min(16, os.cpu_count() or 1)))  # decoding in evaluation

    # The time plan: what is left, less the evaluations and saves, split between the phases.
    n_held = len(held_items)
    eval_est = {s: n_held * EVAL_S_PER_IMAGE_112 * (s / 112) ** 2 + 5 for s in set(sizes)}
    now = time.monotonic()
    reserve = eval_est[config.input_size] + SAFETY_S
    if student_config:
        reserve += eval_est[student_config.input_size] + SAFETY_S
    train_time = budget_end - now - reserve
    if train_time < 5:
        raise DatasetError(f"--minutes {a.minutes:g} leaves {train_time:.0f} s for training "
                           f"after loading ({now - _T0:.0f} s) and evaluation ({reserve:.0f} s)")
    teacher_time = train_time * (1 - a.distill_fraction) if student_config else train_time
    record["plan"] = {"loading_s": round(now - _T0, 1), "train_s": round(train_time, 1),
                      "first_phase_s": round(teacher_time, 1),
                      "eval_reserve_s": round(reserve, 1)}
    settings = {"pos_weight": a.pos_weight, "neg_weight": a.neg_weight,
                "width_weight": a.width_weight, "balance_images": a.balance_images,
                "loss": "weighted", "optimizer": "adam", "augment": not a.no_augment,
                "warmup_steps": a.warmup_steps, "lr_floor": a.lr_floor,
                "schedule": "linear warm-up, cosine over the phase's wall-clock time",
                "precision": "bf16 autocast" if device.type == "cuda" else "float32"}
    record["settings"] = settings
    _write_json(record_path, record)

    torch.manual_seed(a.seed)
    model = GraspAutoencoder(config)
    if init is not None:
        model.load_state_dict(init.state_dict())
    model = model.to(device)
    if device.type == "cuda":
        model = model.to(memory_format=torch.channels_last)
    log(f"{config.name}: {parameter_count(model):,} parameters, input {config.input_size} px, "
        f"batch {a.batch_size}, lr {a.lr:g}, {teacher_time:.0f} s")
    pack_names = [p.path.name for p in packs]
    start = time.monotonic()
    phase = Phase(config.name, model, a.out / f"{config.name}.pt", a.lr, a.batch_size, start,
                  start + teacher_time, a, {})
    heldout_pending = {"objects": held_objects, "pending": True}

    def metrics(ph: Phase, heldout: dict, extra: dict) -> dict:
        return {"training": {"data": pack_names, "packs_sha256": [p["sha256"] for p in
                                                                 record["packs"]],
                             "trainer": "train_ae.gpu", "seed": a.seed, "holdout": holdout,
                             "train_objects": train_objects, "train_images": len(train_idx),
                             "jaw_side_fraction": jaw, **settings, **extra,
                             **ph.summary(len(train_idx))},
                "heldout": heldout}

    def save_teacher() -> None:
        if phase.save(metrics(phase, heldout_pending, {"init": a.init and a.init.name})):
            record["phases"] = {config.name: phase.summary(len(train_idx))}
            _write_json(record_path, record)

    _train(phase, data, train_idx, config.input_size, a, device, save_teacher)
    record["phases"] = {config.name: phase.summary(len(train_idx))}
    if not finite_state(cpu_state(model)):
        model.load_state_dict(phase.good_state)
    s = phase.summary(len(train_idx))
    log(f"{config.name}: {s['steps']} steps, {s['epochs']} epochs, {s['images_per_s']} img/s, "
        f"stopped by {s['stopped']}")
    t_eval = time.monotonic()
    heldout = _evaluate(model, packs, held_items, device, jaw)
    eval_s = time.monotonic() - t_eval
    if heldout is not None and "error" not in heldout:
        log(f"{config.name} held-out objects: {format_result(heldout)} [{eval_s:.1f} s]")
    phase.save(metrics(phase, heldout, {"init": a.init and a.init.name}))
    record["phases"][config.name]["heldout"] = heldout
    record["phases"][config.name]["eval_s"] = round(eval_s, 1)
    outputs = [phase.path]

    if student_config is not None:
        try:
            teacher = model.eval()
            for p in teacher.parameters():
                p.requires_grad_(False)
            torch.manual_seed(a.seed + 1)
            student = GraspAutoencoder(student_config)
            if student_init is not None:
                student.load_state_dict(student_init.state_dict())
            student = student.to(device)
            if device.type == "cuda":
                student = student.to(memory_format=torch.channels_last)
            ratio = (student_config.input_size / config.input_size) ** 2
            est = eval_s * ratio * 1.5 + 5 if heldout is not None else 0.0
            now = time.monotonic()
            deadline = budget_end - est - SAFETY_S
            name = f"{student_config.name}-distilled"
            log(f"{name}: {parameter_count(student):,} parameters, input "
                f"{student_config.input_size} px, batch {a.distill_batch_size}, lr "
                f"{a.distill_lr:g}, teacher weight {a.distill_weight:g}, "
                f"{max(deadline - now, 0):.0f} s")
            sphase = Phase(name, student, a.out / f"{name}.pt", a.distill_lr,
                           a.distill_batch_size, now, deadline, a, {})
            extra = {"init": a.distill_init and a.distill_init.name,
                     "teacher": phase.path.name, "teacher_config": config.name,
                     "distill_weight": a.distill_weight, "distill_loss": "paper (vs teacher)"}

            def save_student() -> None:
                if sphase.save(metrics(sphase, heldout_pending, extra)):
                    record["phases"][name] = sphase.summary(len(train_idx))
                    _write_json(record_path, record)

            if deadline > now:
                _train(sphase, data, train_idx, student_config.input_size, a, device,
                       save_student, teacher, config.input_size)
            s = sphase.summary(len(train_idx))
            log(f"{name}: {s['steps']} steps, {s['epochs']} epochs, {s['images_per_s']} img/s, "
                f"stopped by {s['stopped']}")
            if not finite_state(cpu_state(student)):
                student.load_state_dict(sphase.good_state)
            t_eval = time.monotonic()
            sheld = _evaluate(student, packs, held_items, device, jaw)
            if sheld is not None and "error" not in sheld:
                log(f"{name} held-out objects: {format_result(sheld)} "
                    f"[{time.monotonic() - t_eval:.1f} s]")
            sphase.save(metrics(sphase, sheld, extra))
            record["phases"][name] = {**s, "heldout": sheld,
                                      "eval_s": round(time.monotonic() - t_eval, 1)}
            outputs.append(sphase.path)
        except Exception as e:  # the teacher's files are written: record, do not lose them
            log(f"distillation failed: {e!r}\n{traceback.format_exc()}")
            record["phases"][f"{student_config.name}-distilled"] = {"error": repr(e)}
            student_path = a.out / f"{student_config.name}-distilled.pt"
            if student_path.is_file():
                outputs.append(student_path)

    record["outputs"] = {p.name: _sha256(p) for p in outputs if p.is_file()}
    record["wall_s"] = round(time.monotonic() - _T0, 1)
    record["finished_utc"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    _write_json(record_path, record)
    log(f"wrote {', '.join(record['outputs'])} and {record_path.name} in {a.out} "
        f"({record['wall_s']} s)")
    return record


def main(argv: list[str] | None = None) -> int:
    """The command; called with ``argv`` (tests, other code) the budget starts now, else at
    the module's import (``python -m``: the torch import counts)."""
    global _T0
    if argv is not None:
        _T0 = time.monotonic()
    a = _args(argv)
    try:
        run(a)
    except (DatasetError, PackError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr, flush=True)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
