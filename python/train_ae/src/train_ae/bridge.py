"""The functions the Rust side (crates/pybridge, through pyo3) calls. Keep these stable.

    default_checkpoint() -> str
        Absolute path of the shipped ``cpu`` checkpoint (package data ``weights/cpu.pt``);
        FileNotFoundError if this installation does not have it.
    load(path) -> model
        A checkpoint written by ``python -m train_ae.train``, as a model in eval mode on the CPU.
    input_size(model) -> int
        The square side (pixels) the model was trained at; render or resize to it.
    jaw_side_fraction(model) -> float | None
        Jaw of a decoded grasp as a fraction of the map side (finger width / crop side of the
        training data); None: opening × 0.5 (the Cornell convention; older checkpoints).
    preprocess(rgb: uint8 (H, W, 3), depth: float32 (H, W) metres, size: int | None = None)
            -> float32 (4, S, S)
        The exact training input. With ``size``, a square image of another side is first
        resized to ``size`` with the training resize (``data.resize_to_input``: area averaging
        for an integer factor, e.g. a 224-px crop to 112, else bilinear). Then the training
        normalisation: [depth - mean(depth), RGB/255 - mean]; non-finite depth pixels are set
        to the mean of the finite ones first. Without ``size`` (or at that size already) no
        resizing, any H x W.
    infer(model, rgbd: float32 (N, 4, H, W)) -> (features, quality, cos2t, sin2t, width)
        features float32 (N, 256), L2-normalised; the four grasp maps float32 (N, H, W).
        Width is opening / WIDTH_SCALE_PX (pixels at this resolution); the angle is
        atan2(sin2t, cos2t) / 2, counter-clockwise on screen from +x (see ``train_ae.grasp``).

All arrays are C-contiguous numpy arrays; ``infer`` reads its input without copying when it is
already C-contiguous float32; each output is one fresh array (no per-pixel Python work).

Example::

    from train_ae import bridge
    m = bridge.load(bridge.default_checkpoint())        # or any checkpoint path
    x = bridge.preprocess(rgb, depth, bridge.input_size(m))[None]   # (1, 4, S, S)
    features, quality, cos2t, sin2t, width = bridge.infer(m, x)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .checkpoint import load_checkpoint
from .data import normalize_rgbd, resize_to_input
from .grasp import WIDTH_SCALE_PX
from .model import GraspAutoencoder

__all__ = ["WIDTH_SCALE_PX", "default_checkpoint", "infer", "input_size", "jaw_side_fraction",
           "load", "preprocess"]

DEFAULT_CHECKPOINT = Path(__file__).resolve().parent / "weights" / "cpu.pt"
"""The shipped ``cpu`` checkpoint (package data; how it was made: the package README)."""


def default_checkpoint() -> str:
    """Absolute path of the shipped ``cpu`` checkpoint; FileNotFoundError if it is absent."""
    path = DEFAULT_CHECKPOINT
    if not path.is_file():
        raise FileNotFoundError(
            f"the default train_ae checkpoint {path} is missing: this installation of train_ae "
            f"was built without its package data (reinstall it from the lgdm repository, "
            f"`pip install -e python/train_ae`) or pass a checkpoint path explicitly "
            f"(train one with `python -m train_ae.train`)")
    return str(path)


def load(path: str | Path) -> GraspAutoencoder:
    model, _ = load_checkpoint(path)
    return model


def input_size(model: GraspAutoencoder) -> int:
    return int(model.config.input_size)


def jaw_side_fraction(model: GraspAutoencoder) -> float | None:
    j = model.config.jaw_side_fraction
    return None if j is None else float(j)


def preprocess(rgb: np.ndarray, depth: np.ndarray, size: int | None = None) -> np.ndarray:
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8:
        raise ValueError(f"rgb must be uint8, got {rgb.dtype}")
    if size is not None and tuple(rgb.shape[:2]) != (size, size):
        rgb, depth = resize_to_input(rgb, depth, int(size))  # checks shapes, square
    return np.ascontiguousarray(normalize_rgbd(rgb, depth))


def infer(model: GraspAutoencoder, rgbd: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    arr = np.asarray(rgbd)
    if arr.ndim != 4 or arr.shape[1] != model.config.in_channels:
        raise ValueError(f"rgbd must be (N, {model.config.in_channels}, H, W), got {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError("rgbd is an empty batch")
    x = torch.from_numpy(np.ascontiguousarray(arr, dtype=np.float32))
    if not torch.isfinite(x).all():
        raise ValueError("rgbd contains NaN or infinite values; preprocess() removes them")
    model.eval()
    with torch.inference_mode():
        features, maps = model.forward_with_features(x)
    q, c, s, w = (m.contiguous().numpy() for m in maps)
    return features.contiguous().numpy(), q, c, s, w
