"""Data access: datasets as numpy arrays with labels, GOOD descriptors and feature tables, the
same values Rust computes for the command line."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import lgdm


def test_manifest_views(small_dataset):
    ds = small_dataset
    assert len(ds.categories) == 10 and "mug" in ds.categories
    assert len(ds.instances) == 30
    assert all(0 <= inst["category"] < 10 for inst in ds.instances)
    assert [c["index"] for c in ds.collections] == list(range(15))
    assert ds.manifest["frames_per_sequence"] == 4
    train, test = ds.split("train"), ds.split("test")
    assert len(train) == 12 and len(test) == 3 and not set(train) & set(test)
    assert "30 instances" in repr(ds)
    assert lgdm.Dataset(ds.path).manifest == ds.manifest


def test_sequences_are_numpy_with_labels(small_dataset):
    ds = small_dataset
    seen = []
    for frames, info in ds.sequences(13):
        assert len(frames) == 4
        for points in frames:
            assert points.dtype == np.float32 and points.ndim == 2 and points.shape[1] == 3
            assert len(points) > 50 and np.isfinite(points).all()
            assert 0.2 < np.median(points[:, 2]) < 3.0  # in front of the camera, metres
        assert info["collection"] == 13
        assert info["category"] == ds.instances[info["instance"]]["category"]
        assert info["category_name"] == ds.categories[info["category"]]
        assert info["instance_name"] == ds.instances[info["instance"]]["name"]
        assert info["collection_name"] == ds.collections[13]["name"]
        if info["colors"] is not None:
            assert [c.shape for c in info["colors"]] == [p.shape for p in frames]
            assert info["colors"][0].dtype == np.uint8
        seen.append(info["instance"])
    assert sorted(seen) == list(range(30))
    assert len({info["sequence"] for _, info in ds.sequences(0)}) == 30


def test_good_descriptor_matches_the_feature_table(small_dataset):
    ds = small_dataset
    table = lgdm.good_features(ds)
    n = ds.manifest["views"]
    assert table["features"].shape == (n, 675) and table["features"].dtype == np.float32
    for key in ("collection", "category", "instance", "sequence", "frame"):
        assert table[key].shape == (n,) and table[key].dtype == np.int64
    frames, info = next(iter(ds.sequences(2)))
    for f, points in enumerate(frames):
        row = np.flatnonzero(
            (table["collection"] == 2)
            & (table["instance"] == info["instance"])
            & (table["frame"] == f)
        )
        assert len(row) == 1
        np.testing.assert_array_equal(lgdm.good_descriptor(points), table["features"][row[0]])
        assert table["sequence"][row[0]] == info["sequence"]
    # Three projections, each normalised to sum 1.
    sums = table["features"][:5].reshape(5, 3, 225).sum(axis=2)
    np.testing.assert_allclose(sums, 1.0, atol=1e-4)
    # The directory works as well as the opened dataset, and gives the same values.
    np.testing.assert_array_equal(
        lgdm.good_features(ds.path, bins=5)["features"][:3].shape, (3, 75)
    )


def test_good_descriptor_is_pose_invariant():
    rng = np.random.default_rng(0)
    points = rng.normal(0, 1, (2000, 3)) * [0.10, 0.05, 0.02]
    angle = 0.7
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]]
    )
    moved = points @ rot.T + [0.3, -0.2, 1.0]
    a, b = lgdm.good_descriptor(points), lgdm.good_descriptor(moved)
    assert a.shape == (675,)
    assert np.abs(a - b).sum() < 0.05 * np.abs(a).sum()
    assert lgdm.good_descriptor(points.astype(np.float32), bins=3).shape == (27,)


@pytest.mark.parametrize(
    ("points", "bins", "error", "message"),
    [
        (np.zeros((0, 3)), 15, lgdm.InputError, "empty"),
        (np.zeros((10, 2)), 15, lgdm.InputError, r"shape \(N, 3\)"),
        (np.zeros(30), 15, lgdm.InputError, r"shape \(N, 3\)"),
        (np.full((10, 3), np.nan), 15, lgdm.InputError, "finite|NaN"),
        (np.array([["a", "b", "c"]]), 15, lgdm.InputError, "real numbers"),
        (np.ones((10, 3)), 0, lgdm.InputError, "bins"),
    ],
)
def test_good_descriptor_errors(points, bins, error, message):
    with pytest.raises(error, match=message):
        lgdm.good_descriptor(points, bins=bins)


def test_dataset_errors(small_dataset, tmp_path):
    with pytest.raises(lgdm.DatasetError, match=r"manifest\.json"):
        lgdm.Dataset(tmp_path / "nothing-here")
    with pytest.raises(lgdm.DatasetError, match="no collection 99"):
        small_dataset.sequences(99)
    with pytest.raises(lgdm.InputError, match="unknown split"):
        small_dataset.split("validation")
    with pytest.raises(lgdm.DatasetError, match="unknown preset"):
        lgdm.generate_dataset(tmp_path / "x", "huge")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(lgdm.DatasetError, match="not empty"):
        lgdm.generate_dataset(tmp_path / "busy")
    # A truncated collection file is refused when the dataset is opened.
    copy = tmp_path / "copy"
    shutil.copytree(small_dataset.path, copy)
    target = copy / small_dataset.collections[3]["file"]
    target.write_bytes(target.read_bytes()[:-100])
    with pytest.raises(lgdm.DatasetError, match="truncated"):
        lgdm.Dataset(copy)


def test_projection_to_rgbd_image(small_dataset):
    frames, info = next(iter(small_dataset.sequences(0)))
    colors = None if info["colors"] is None else info["colors"][0]
    image = lgdm.project_to_image(frames[0], colors)
    depth = image["depth_m"]
    assert depth.shape == (224, 224) and depth.dtype == np.float32
    filled = depth > 0
    assert 0.1 < filled.mean() < 0.95, "the object fills a good part of the image"
    z = frames[0][:, 2]
    assert z.min() - 1e-6 <= depth[filled].min() and depth[filled].max() <= z.max() + 1e-6
    norm = image["depth_normalized"]
    assert norm.shape == (224, 224) and norm[~filled].max() == 0 and norm.max() == 1.0
    if colors is not None:
        assert image["rgb"].shape == (224, 224, 3) and image["rgb"].dtype == np.uint8
        assert image["rgb"][filled].any()
    else:
        assert image["rgb"] is None
    small = lgdm.project_to_image(frames[0], size=32, splat_px=1)
    assert small["depth_m"].shape == (32, 32) and small["rgb"] is None


def test_best_view_prefers_the_larger_silhouette():
    rng = np.random.default_rng(0)
    wide = np.column_stack(
        [rng.uniform(-0.1, 0.1, 3000), rng.uniform(-0.1, 0.1, 3000), np.ones(3000)]
    )
    thin = wide * [0.05, 1, 1]  # an edge-on view
    assert lgdm.view_entropy(wide) > lgdm.view_entropy(thin)
    assert lgdm.best_view([thin, wide, thin]) == 1
    assert lgdm.best_view([]) is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": np.zeros((5, 3))}, "in front of the camera"),
        ({"points": np.ones((5, 3)), "colors": np.zeros((4, 3), np.uint8)}, r"shape \(5, 3\)"),
        ({"points": np.ones((5, 3)), "colors": np.full((5, 3), 0.5)}, "uint8"),
        ({"points": np.ones((5, 3)), "colors": np.full((5, 3), 300)}, "0..255"),
        ({"points": np.ones((5, 3)), "size": 0}, "size"),
        ({"points": np.ones((5, 3)), "margin": 0.7}, "margin"),
        ({"points": np.ones((5, 2))}, r"shape \(N, 3\)"),
    ],
)
def test_projection_errors(kwargs, message):
    with pytest.raises(lgdm.InputError, match=message):
        lgdm.project_to_image(**kwargs)
