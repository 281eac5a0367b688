"""Pack grasp-image directories into one compact file, for a machine that has no lgdm.

    python -m train_ae.pack --data DIR [--data DIR ...] --out FILE [--size N] [--max-mib 55]
        [--note TEXT]

Reads every ``--data`` directory the way ``train_ae.train`` does (``data.find_samples_in``:
``lgdm gen-dataset``'s geometric ``grasp/`` images and ``lgdm sim grasp-data``'s physics sets
alike, the jaws must agree) and writes one zip of ``.npy`` arrays (``numpy.load`` reads it;
nothing is pickled):

* ``rgb`` uint8 (N, S, S, 3); ``depth`` uint16 (N, S, S): metres as ``depth_base[i] + q *
  depth_step_m`` (``DEPTH_STEP_M``, 0.2 mm; ``DEPTH_NONFINITE`` marks a pixel without depth),
  stored as differences along each row (mod 2^16), which deflate packs far better;
  ``depth_base`` float64 (N,);
* ``corners`` float32 (R, 4, 2): every rectangle's corners (NaN rectangles skipped, as the
  loader does), image by image, its positives first; read back as the shortest decimal of
  each float32, which is what lgdm writes, so the reader gets the very float64 values that
  ``float()`` of the file's text gives; ``corners_fix_at`` / ``corners_fix`` (int64 / float64)
  hold the few values where that decimal differs (a tie printed the other way, or a file not
  written from float32); ``positives``, ``negatives`` int32 (N,): how many of each per image;
* ``dataset`` uint16 (N,) into the manifest's ``datasets``; ``prefix``, ``object``, ``category``
  (unicode; "" = no category): each image's place in its directory and the split's keys;
* ``manifest``: UTF-8 JSON (uint8): format, size, depth step, jaw, totals, and per input
  directory its name, kind (``geometric`` or ``physics``), images, objects, categories,
  rectangle counts, its ``index.json`` header and the generator seed and settings its
  command recorded (``../manifest.json`` of a gen-dataset ``grasp/`` directory,
  ``grasp-data.json`` of a grasp-data one).

``--size N`` (default: the images' own side) resizes the crops with training's resize
(``data.resize_to_input``) and scales the rectangles to match; at the native size the arrays
are the files' pixels. The file is refused — an error, nothing written — when it would exceed
``--max-mib``. Same inputs, same bytes: the zip's entries are in a fixed order with fixed
timestamps. ``read_pack`` reads it back; ``PackedGraspDataset`` serves it as a
``data.GraspDataset`` (evaluation path: the same resize, normalisation and label maps).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .data import (
    DatasetError,
    GraspDataset,
    Sample,
    find_samples,
    find_samples_in,
    load_images,
    read_grasp_index,
    read_rectangles,
    resize_to_input,
)
from .grasp import GraspRectangle

FORMAT = "lgdm.train_ae.pack.v1"
"""Value of the manifest's ``format``."""

DEPTH_STEP_M = 2e-4
"""Depth quantum (0.2 mm): a fifth of a 224-px crop's 1 mm pixel; the robot's depth
noise (grasp-data: up to 1.5 mm) is coarser."""

DEPTH_NONFINITE = 65535
"""Quantised value of a pixel without a finite depth (read back as NaN)."""

DEFAULT_MAX_MIB = 55.0
"""The default cap: with the working tree (~8 MiB) under the device machine's 64 MiB (61 MiB of pack
was refused there, 54.5 MiB went)."""
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)
_ARRAYS = ("manifest", "rgb", "depth", "depth_base", "corners", "corners_fix_at", "corners_fix",
           "positives", "negatives", "dataset", "prefix", "object", "category")


class PackError(ValueError):
    """A pack cannot be written (too large, bad input) or read (not a pack, inconsistent)."""


# --- writing -------------------------------------------------------------------------------------

def dataset_name(root: Path) -> str:
    """A directory's name in the manifest: its own, or ``<parent>/grasp`` for a gen-dataset
    ``grasp/`` folder (``data-seed3/grasp``)."""
    root = Path(root)
    return f"{root.parent.name}/{root.name}" if root.name == "grasp" else root.name


def _source_record(root: Path) -> dict | None:
    """The generating command's own record beside the images: ``grasp-data.json`` in the
    directory, or gen-dataset's ``manifest.json`` one level up; its seed and settings only
    (lists of per-item records are dropped)."""
    for path in (root / "grasp-data.json", root.parent / "manifest.json"):
        if not path.is_file():
            continue
        try:
            raw = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        if not isinstance(raw, dict):
            continue
        return {"file": path.name, **_small(raw)}
    return None


def _small(record: dict, depth: int = 0) -> dict:
    """A record without its lists and without values over 4 KB of JSON; a large object keeps
    its small values (two levels: grasp-data's ``setup`` keeps its seed, not its config)."""
    out = {}
    for k, v in record.items():
        if isinstance(v, list):
            continue
        if len(json.dumps(v)) <= 4096:
            out[k] = v
        elif isinstance(v, dict) and depth < 1:
            out[k] = _small(v, depth + 1)
    return out


def _find_seed(record: dict | None) -> int | None:
    """``seed`` at the record's top level or one level down (e.g. ``config.seed``)."""
    if not record:
        return None
    if isinstance(record.get("seed"), int):
        return record["seed"]
    for v in record.values():
        if isinstance(v, dict) and isinstance(v.get("seed"), int):
            return v["seed"]
    return None


def _quantise_depth(depth: np.ndarray) -> tuple[np.ndarray, float]:
    """(row-differenced uint16 (H, W), base metres) of a float32 depth image."""
    ok = np.isfinite(depth)
    base = float(depth[ok].min()) if ok.any() else 0.0
    q = np.full(depth.shape, DEPTH_NONFINITE, np.int64)
    q[ok] = np.rint((depth[ok].astype(np.float64) - base) / DEPTH_STEP_M).astype(np.int64)
    if ok.any() and q[ok].max() >= DEPTH_NONFINITE:
        span = float(depth[ok].max()) - base
        raise PackError(f"depth spans {span:.3f} m in one image, more than the "
                        f"{(DEPTH_NONFINITE - 1) * DEPTH_STEP_M:.3f} m a pack holds")
    q = q.astype(np.uint16)
    return np.diff(q, axis=1, prepend=np.uint16(0)), base


def _dequantise_depth(diffs: np.ndarray, base: np.ndarray) -> np.ndarray:
    """float32 (N, H, W) metres, NaN where no depth, from ``_quantise_depth``'s arrays."""
    depth = np.empty(diffs.shape, np.float32)
    for i in range(0, len(diffs), 64):  # in chunks: a pack's depth is a few GB as float32
        q = np.cumsum(diffs[i:i + 64], axis=-1, dtype=np.uint16)
        d = depth[i:i + 64]
        np.multiply(q, np.float32(DEPTH_STEP_M), out=d, dtype=np.float32)
        d += base[i:i + 64, None, None].astype(np.float32)
        d[q == DEPTH_NONFINITE] = np.nan
    return depth


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def _unicode(values: list[str]) -> np.ndarray:
    width = max([1, *map(len, values)])
    return np.array(values, dtype=f"<U{width}")


def _scaled(r: np.ndarray, n: int, size: int) -> np.ndarray:
    """Corners (4, 2) of an n-px crop in a size-px one (pixel centres aligned, as training)."""
    return (r + 0.5) * (size / n) - 0.5


def build_pack(roots: list[Path], size: int | None = None, progress=None,
               note: str | None = None) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays by name, manifest) of the directories, in ``roots``' order; ``note``: free text
    kept in the manifest (e.g. which lgdm build generated the data)."""
    roots = [Path(r) for r in roots]
    names = [dataset_name(r) for r in roots]
    if len(set(names)) != len(names):
        raise PackError(f"two directories would have the same name in the pack: {names}")
    _, jaw = find_samples_in(roots)  # the directories' checks, the jaw they agree on
    per_root = [find_samples(r) for r in roots]
    samples = [s for part in per_root for s in part]
    n_img = len(samples)
    rgb0, _ = load_images(samples[0])
    native = rgb0.shape[0]
    side = int(size) if size is not None else native
    if side < 16 or side % 4:
        raise PackError(f"--size must be a multiple of 4 and at least 16, got {side}")
    rgb = np.empty((n_img, side, side, 3), np.uint8)
    depth = np.empty((n_img, side, side), np.uint16)
    base = np.empty(n_img, np.float64)
    corners: list[np.ndarray] = []
    pos = np.zeros(n_img, np.int32)
    neg = np.zeros(n_img, np.int32)
    ds_index = np.zeros(n_img, np.uint16)
    prefixes, objects, categories = [], [], []
    datasets = []
    i = 0
    for d, (root, name, part) in enumerate(zip(roots, names, per_root, strict=True)):
        skipped = n_pos = n_neg = 0
        for s in part:
            im_rgb, im_depth = load_images(s)
            if im_rgb.shape[:2] != (native, native):
                raise PackError(f"{s.rgb_path}: {im_rgb.shape[1]}x{im_rgb.shape[0]} px, the "
                                f"pack's crops are {native}x{native} (square, one size)")
            if side != native:
                f_rgb, f_depth = resize_to_input(im_rgb, im_depth, side)
                im_rgb = np.clip(np.rint(f_rgb), 0, 255).astype(np.uint8)
                im_depth = f_depth
            rgb[i] = im_rgb
            depth[i], base[i] = _quantise_depth(im_depth)
            for path, count in ((s.cpos_path, pos), (s.cneg_path, neg)):
                if path is None:
                    continue
                rects, nan = _read_corners(path)
                skipped += nan
                count[i] = len(rects)
                corners.extend(_scaled(c, native, side) if side != native else c
                               for c in rects)
            n_pos += int(pos[i])
            n_neg += int(neg[i])
            ds_index[i] = d
            prefixes.append(f"{s.rgb_path.parent.name}/{s.stem}")
            objects.append(s.object_id)
            categories.append(s.category or "")
            i += 1
            if progress is not None:
                progress(i, n_img)
        index = read_grasp_index(root)
        source = _source_record(root)
        datasets.append({
            "name": name,
            "kind": "physics" if any(s.physics is not None for s in part) else "geometric",
            "images": len(part),
            "objects": len({s.object_id for s in part}),
            "categories": sorted({s.category for s in part if s.category is not None}),
            "positives": n_pos,
            "negatives": n_neg,
            "skipped_nan_rectangles": skipped,
            "seed": _find_seed(source),
            "index": None if index is None else {
                "crop_side_m": index.crop_side_m, "crop_size_px": index.crop_size_px,
                "finger_width_m": index.finger_width_m,
                "jaw_side_fraction": index.jaw_side_fraction},
            "source": source,
        })
    manifest = {
        "format": FORMAT,
        "size": side,
        "source_size": native,
        "depth_step_m": DEPTH_STEP_M,
        "depth_nonfinite": DEPTH_NONFINITE,
        "depth_encoding": "uint16 differences along rows of (depth - depth_base) / step",
        "jaw_side_fraction": jaw,
        "images": n_img,
        "positives": int(pos.sum()),
        "negatives": int(neg.sum()),
        "datasets": datasets,
        "note": note,
    }
    arrays = {
        "manifest": np.frombuffer(json.dumps(manifest, sort_keys=True).encode(), np.uint8),
        "rgb": rgb,
        "depth": depth,
        "depth_base": base,
        **_encode_corners(np.stack(corners) if corners else np.zeros((0, 4, 2))),
        "positives": pos,
        "negatives": neg,
        "dataset": ds_index,
        "prefix": _unicode(prefixes),
        "object": _unicode(objects),
        "category": _unicode(categories),
    }
    return arrays, manifest


def _decode_corners(c32: np.ndarray) -> np.ndarray:
    """float64 values of float32 corners: each one's shortest decimal, parsed."""
    return c32.astype(str).astype(np.float64) if c32.size else c32.astype(np.float64)


def _encode_corners(corners: np.ndarray) -> dict[str, np.ndarray]:
    c32 = corners.astype(np.float32)
    back = _decode_corners(c32)
    at = np.flatnonzero(back.ravel() != corners.ravel())
    return {"corners": c32, "corners_fix_at": at.astype(np.int64),
            "corners_fix": corners.ravel()[at].astype(np.float64)}


def _read_corners(path: Path) -> tuple[list[np.ndarray], int]:
    """The (4, 2) corners of a rectangle file's valid rectangles (``data.read_rectangles``
    checks and skips them), and the number skipped for NaNs."""
    rects, skipped = read_rectangles(path)
    del rects  # validated; the corners themselves are kept as written
    points = np.array([[float(v) for v in line.split()] for line in path.read_text().splitlines()
                       if line.strip()], dtype=np.float64).reshape(-1, 4, 2)
    return [c for c in points if not np.isnan(c).any()], skipped


def write_pack(arrays: dict[str, np.ndarray], out: Path, max_mib: float = DEFAULT_MAX_MIB
               ) -> int:
    """Writes the zip atomically; its size in bytes. Over ``max_mib``: ``PackError``, no file."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
        for name in _ARRAYS:
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, _npy_bytes(arrays[name]), compresslevel=9)
    data = buf.getvalue()
    limit = int(max_mib * 1024 * 1024)
    if len(data) > limit:
        raise PackError(f"the pack would be {len(data) / 2**20:.1f} MiB, more than --max-mib "
                        f"{max_mib:g}: pack fewer directories or a smaller --size; nothing "
                        f"written")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return len(data)


# --- reading -------------------------------------------------------------------------------------

@dataclass
class Pack:
    """A pack read back: images as the loader gives them, rectangles, samples and manifest."""

    path: Path
    manifest: dict
    rgb: np.ndarray
    """uint8 (N, S, S, 3)."""
    depth: np.ndarray
    """float32 (N, S, S) metres, NaN where the image had no finite depth."""
    positives: list[list[GraspRectangle]]
    negatives: list[list[GraspRectangle]]
    samples: list[Sample]
    """One per image: object, category and a path naming where it came from
    (``<dataset>/<prefix>r.png``, not a file)."""

    @property
    def size(self) -> int:
        return int(self.manifest["size"])

    @property
    def jaw_side_fraction(self) -> float | None:
        return self.manifest["jaw_side_fraction"]

    def __len__(self) -> int:
        return len(self.samples)


def read_pack(path: str | Path) -> Pack:
    """A pack file as arrays, ``GraspRectangle`` lists (the same objects ``data.
    load_rectangles`` makes from the files) and ``Sample`` records."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = sorted(set(_ARRAYS) - {k for k in z.files})
            if missing:
                raise PackError(f"{path}: not a train_ae pack (no {', '.join(missing)})")
            a = {k: z[k] for k in _ARRAYS}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        if isinstance(e, PackError):
            raise
        raise PackError(f"{path}: not a readable pack: {e}") from e
    manifest = json.loads(bytes(a["manifest"]).decode())
    if manifest.get("format") != FORMAT:
        raise PackError(f"{path}: format is {manifest.get('format')!r}, expected {FORMAT!r}")
    n = int(manifest["images"])
    pos_n, neg_n = a["positives"].astype(np.int64), a["negatives"].astype(np.int64)
    if (len(a["rgb"]) != n or len(pos_n) != n or int(pos_n.sum() + neg_n.sum())
            != len(a["corners"])):
        raise PackError(f"{path}: array lengths disagree with the manifest's {n} images")
    corners = _decode_corners(a["corners"])
    corners.reshape(-1)[a["corners_fix_at"]] = a["corners_fix"]
    positives, negatives, samples = [], [], []
    k = 0
    names = [d["name"] for d in manifest["datasets"]]
    for i in range(n):
        p = [GraspRectangle.from_corners(c) for c in corners[k:k + pos_n[i]]]
        k += pos_n[i]
        q = [GraspRectangle.from_corners(c) for c in corners[k:k + neg_n[i]]]
        k += neg_n[i]
        positives.append(p)
        negatives.append(q)
        ds = names[int(a["dataset"][i])]
        prefix = str(a["prefix"][i])
        where = Path(ds) / f"{prefix}r.png"
        samples.append(Sample(str(a["object"][i]), where, where, where, None,
                              str(a["category"][i]) or None, None))
    depth = _dequantise_depth(a["depth"], a["depth_base"])
    return Pack(path, manifest, a["rgb"], depth, positives, negatives, samples)


def dataset_of(sample: Sample) -> str:
    """The pack's dataset name of one of its samples."""
    return str(Path(*sample.rgb_path.parts[:-2]))


class PackedGraspDataset(GraspDataset):
    """Images of a pack (or several) as a ``data.GraspDataset`` without augmentation: the same
    ``_render`` (resize, normalisation, label maps) on the pack's arrays; what
    ``training.evaluate_model`` scores."""

    def __init__(self, packs: list[Pack], items: list[tuple[int, int]], input_size: int):
        super().__init__([packs[p].samples[i] for p, i in items], input_size, augment=False)
        self.packs = packs
        self.items = list(items)

    def item(self, index: int, epoch: int = 0):
        p, i = self.items[index]
        pack = self.packs[p]
        return self._render(pack.rgb[i], pack.depth[i],
                            (pack.positives[i], pack.negatives[i]))


# --- command -------------------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m train_ae.pack", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path, action="append", metavar="DIR",
                   help="a grasp-image directory (repeatable; in this order)")
    p.add_argument("--out", required=True, type=Path, help="pack file to write (.npz)")
    p.add_argument("--size", type=int, help="crop side in the pack (default: the images')")
    p.add_argument("--max-mib", type=float, default=DEFAULT_MAX_MIB,
                   help=f"refuse a pack larger than this (default {DEFAULT_MAX_MIB:g} MiB)")
    p.add_argument("--note", help="free text for the manifest (e.g. the lgdm build)")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    if not a.max_mib > 0:
        p.error("--max-mib must be positive")

    def progress(done: int, total: int) -> None:
        if not a.quiet and (done == total or done % max(total // 10, 1) == 0):
            print(f"packed {done}/{total} images", file=sys.stderr, flush=True)

    try:
        arrays, manifest = build_pack(a.data, a.size, progress, a.note)
        nbytes = write_pack(arrays, a.out, a.max_mib)
    except (PackError, DatasetError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for d in manifest["datasets"]:
        print(f"{d['name']}: {d['kind']}, {d['images']} images of {d['objects']} objects, "
              f"{d['positives']} positive and {d['negatives']} negative rectangles, seed "
              f"{d['seed']}", file=sys.stderr)
    print(f"wrote {a.out}: {manifest['images']} images at {manifest['size']} px, "
          f"{nbytes / 2**20:.1f} MiB", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
