"""Data access: datasets written by ``lgdm gen-dataset``, the GOOD descriptor, dataset-wide
GOOD feature tables and dataset generation. The work is done in Rust (``lgdm_pointcloud``),
the same code the command line runs, with the GIL released.

Example::

    ds = lgdm.Dataset("data/")
    for frames, info in ds.sequences(0):
        descriptors = [lgdm.good_descriptor(points) for points in frames]
    table = lgdm.good_features(ds)          # {"features": (n, 675) float32, "category": ...}
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from . import _lgdm
from ._errors import InputError

__all__ = ["Dataset", "generate_dataset", "good_descriptor", "good_features"]

Dataset = _lgdm.Dataset


def _points(points: Any) -> np.ndarray:
    try:
        arr = np.asarray(points)
    except Exception as e:
        raise InputError(f"points could not be read as a numeric array: {e}") from e
    if arr.dtype.kind not in "fiu":
        raise InputError(f"points must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"points must have shape (N, 3), got {arr.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        return np.ascontiguousarray(arr, dtype=np.float32)


def good_descriptor(points: Any, bins: int = 15) -> np.ndarray:
    """The GOOD shape descriptor (Kasaei et al. 2016) of one point cloud.

    ``points``: (N, 3) coordinates in metres (any real dtype, converted to float32).
    Returns ``3 * bins**2`` float32 values (675 for 15 bins): three orthographic projections
    in a PCA local frame, each normalised to sum 1. Raises :class:`InputError` for an empty
    cloud, NaN/infinite coordinates or ``bins < 1``.
    """
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise InputError(f"bins must be an integer ≥ 1, got {bins!r}")
    return _lgdm.good_descriptor(_points(points), int(bins))


def good_features(
    dataset: Dataset | str | os.PathLike[str], bins: int = 15
) -> dict[str, np.ndarray]:
    """GOOD features of every view of a dataset (a :class:`Dataset` or its directory), in
    collection, file and frame order, computed on all cores.

    Returns a dict of numpy arrays with one row per view: ``features`` (n, 3·bins²) float32 and
    int64 ``collection``, ``category``, ``instance``, ``sequence`` (unique per collection and
    object) and ``frame``. The values are those ``lgdm train``/``lgdm eval`` use.
    """
    if not isinstance(dataset, Dataset):
        dataset = Dataset(os.fspath(dataset))
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise InputError(f"bins must be an integer ≥ 1, got {bins!r}")
    return _lgdm.good_features(dataset, int(bins))


def generate_dataset(
    out: str | os.PathLike[str],
    preset: str = "small",
    seed: int = 0,
    *,
    frames: int | None = None,
    grasp_images: int | None = None,
    meshes: str | os.PathLike[str] | None = None,
) -> Dataset:
    """Generates a sequential point-cloud dataset into ``out`` and opens it, exactly as
    ``lgdm gen-dataset --out OUT --preset PRESET --seed SEED [--frames N] [--grasp-images N]
    [--meshes DIR]`` does (same files). ``preset``: ``"small"`` (10 categories × 3 instances,
    15 collections, 10 frames per sequence) or ``"paper"`` (10 × 5, 100 frames)."""
    return _lgdm.generate_dataset(
        os.fspath(out),
        preset,
        seed,
        frames=frames,
        grasp_images=grasp_images,
        meshes=None if meshes is None else os.fspath(meshes),
    )
