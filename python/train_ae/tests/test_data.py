"""The Cornell-layout loader, object-wise splits, normalisation and augmentation consistency."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from train_ae.data import (
    DatasetError,
    GraspDataset,
    find_samples,
    load_images,
    load_rectangles,
    normalize_rgbd,
    read_object_map,
    read_rectangles,
    split_by_object,
)
from train_ae.grasp import GraspRectangle, grasp_maps
from train_ae.synthetic import TABLE_DEPTH_M


def test_finds_every_sample_with_its_object(fixture_dir):
    samples = find_samples(fixture_dir)
    assert len(samples) == 12
    assert [s.object_id for s in samples] == [f"{i:02d}" for i in range(1, 5) for _ in range(3)]
    assert samples[0].stem == "pcd0000"
    rgb, depth = load_images(samples[0])
    assert rgb.shape == (128, 160, 3) and rgb.dtype == np.uint8
    assert depth.shape == (128, 160) and depth.dtype == np.float32
    assert TABLE_DEPTH_M - 0.1 < depth.min() < depth.max() < TABLE_DEPTH_M + 0.05
    rects = load_rectangles(samples[0])
    assert len(rects.positives) == 1 and len(rects.negatives) == 1 and rects.skipped_nan == 0
    # The grasp sits on the box: the depth under its centre is above the table.
    g = rects.positives[0]
    assert depth[round(g.center_y), round(g.center_x)] < TABLE_DEPTH_M - 0.02


def test_rectangle_file_round_trip(tmp_path):
    r = GraspRectangle(40.5, 30.25, 0.4, 33.0, 12.0)
    path = tmp_path / "pcd0000cpos.txt"
    path.write_text("\n".join(f"{x:.4f} {y:.4f}" for x, y in r.corners()) + "\n")
    (back,), skipped = read_rectangles(path)
    assert skipped == 0
    assert back.angle == pytest.approx(r.angle, abs=1e-4)
    assert (back.center_x, back.center_y, back.width_px, back.jaw_px) == pytest.approx(
        (r.center_x, r.center_y, r.width_px, r.jaw_px), abs=1e-3)


def _copy_one(fixture_dir, tmp_path):
    dst = tmp_path / "data"
    shutil.copytree(fixture_dir / "01", dst / "01")
    return dst


def test_malformed_cpos_is_a_clear_error(fixture_dir, tmp_path):
    root = _copy_one(fixture_dir, tmp_path)
    cpos = root / "01" / "pcd0000cpos.txt"
    lines = cpos.read_text().splitlines()
    cpos.write_text("\n".join(lines[:3]) + "\n")  # a rectangle with three corners
    (s, *_) = find_samples(root)
    with pytest.raises(DatasetError, match=r"pcd0000cpos\.txt: 3 corner lines is not a multiple"):
        load_rectangles(s)
    cpos.write_text("\n".join([*lines[:2], "12.0 abc", lines[3]]) + "\n")
    with pytest.raises(DatasetError, match=r"pcd0000cpos\.txt:3: not a number"):
        load_rectangles(s)
    cpos.write_text("\n".join([*lines[:2], "1 2 3", lines[3]]) + "\n")
    with pytest.raises(DatasetError, match=r"pcd0000cpos\.txt:3: expected two numbers"):
        load_rectangles(s)


def test_nan_rectangles_are_skipped_and_counted(tmp_path):
    path = tmp_path / "pcd0001cpos.txt"
    good = GraspRectangle(20, 20, 0.0, 20, 10).corners()
    rows = [f"{x} {y}" for x, y in good] + ["NaN NaN"] * 4
    path.write_text("\n".join(rows) + "\n")
    rects, skipped = read_rectangles(path)
    assert len(rects) == 1 and skipped == 1


def test_missing_depth_names_the_file_and_the_point_cloud_layout(fixture_dir, tmp_path):
    root = _copy_one(fixture_dir, tmp_path)
    (root / "01" / "pcd0000d.tiff").unlink()
    (root / "01" / "pcd0000.txt").write_text("# .PCD v.7\n")
    with pytest.raises(DatasetError, match=r"pcd0000d\.tiff is missing.*point clouds"):
        find_samples(root)


def test_empty_or_missing_directory_is_an_error(tmp_path):
    with pytest.raises(DatasetError, match="does not exist"):
        find_samples(tmp_path / "nope")
    with pytest.raises(DatasetError, match=r"no pcdNNNNr\.png"):
        find_samples(tmp_path)


def test_split_holds_out_whole_objects(fixture_dir):
    samples = find_samples(fixture_dir)
    train, held = split_by_object(samples, 0.25, seed=3)
    train_objs = {s.object_id for s in train}
    held_objs = {s.object_id for s in held}
    assert len(held_objs) == 1 and len(train_objs) == 3
    assert not train_objs & held_objs
    assert len(train) + len(held) == len(samples)
    assert split_by_object(samples, 0.25, seed=3) == (train, held)
    assert split_by_object(samples, 0.0, seed=3) == (samples, [])
    # Never everything: at least one object stays for training.
    assert len({s.object_id for s in split_by_object(samples, 0.99, seed=0)[0]}) == 1


def test_object_map_overrides_folders(fixture_dir, tmp_path):
    m = tmp_path / "objects.txt"
    m.write_text("# stem object\n" + "".join(f"pcd{i:04d} obj{i % 2}\n" for i in range(12)))
    samples = find_samples(fixture_dir, read_object_map(m))
    assert {s.object_id for s in samples} == {"obj0", "obj1"}
    m.write_text("pcd0000 a\n")
    with pytest.raises(DatasetError, match="no entry for pcd0001"):
        find_samples(fixture_dir, read_object_map(m))


def test_normalisation():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (8, 12, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 0.9, (8, 12)).astype(np.float32)
    depth[0, 0] = np.nan
    x = normalize_rgbd(rgb, depth)
    assert x.shape == (4, 8, 12) and x.dtype == np.float32
    assert np.isfinite(x).all()
    assert abs(x[0].mean()) < 1e-6 and abs(x[1:].mean()) < 1e-6
    assert x[0, 0, 0] == pytest.approx(0.0, abs=1e-6)  # NaN -> mean -> 0
    np.testing.assert_allclose(x[1:] - x[1:].min(),
                               (rgb.transpose(2, 0, 1) - rgb.min()) / 255.0, atol=1e-6)


def test_rotation_moves_image_and_labels_together(fixture_dir):
    ds = GraspDataset(find_samples(fixture_dir), input_size=112, augment=False)
    x0, y0, r0 = ds.render(1, zoom=0.8, rot90=0, center_on_grasps=True)
    for k in (1, 2, 3):
        x, y, r = ds.render(1, zoom=0.8, rot90=k, center_on_grasps=True)
        np.testing.assert_allclose(x, np.rot90(x0, k, axes=(1, 2)), atol=1e-6)
        np.testing.assert_array_equal(y[0], np.rot90(y0[0], k))
        np.testing.assert_allclose(r[0].angle % math.pi, (r0[0].angle + k * math.pi / 2) % math.pi,
                                   atol=1e-9)
        # cos 2θ and sin 2θ follow θ + k·90°: cos 2θ flips sign on odd k.
        np.testing.assert_allclose(y[1], np.rot90(y0[1], k) * (-1) ** k, atol=1e-6)


@pytest.mark.parametrize("zoom", [1.0, 0.6])
def test_zoom_keeps_rectangles_on_their_object(fixture_dir, zoom):
    samples = find_samples(fixture_dir)
    ds = GraspDataset(samples, input_size=112, augment=False)
    for i in range(len(samples)):
        x, y, rects = ds.render(i, zoom=zoom, rot90=i % 4, center_on_grasps=True)
        g = rects[0]
        rgb, _ = load_images(samples[i])
        scale = 112 / (min(rgb.shape[:2]) * zoom)
        raw = load_rectangles(samples[i]).positives[0]
        assert g.width_px == pytest.approx(raw.width_px * scale, rel=0.02)
        # Depth channel (mean-subtracted) under the grasp centre: the box, nearer than average.
        assert x[0, round(g.center_y), round(g.center_x)] < -0.01
        np.testing.assert_array_equal(y, np.stack(grasp_maps(rects, (112, 112))))


def test_augmentation_is_seeded_by_seed_epoch_and_index(fixture_dir):
    samples = find_samples(fixture_dir)
    a = GraspDataset(samples, 112, augment=True, seed=5)
    b = GraspDataset(samples, 112, augment=True, seed=5)
    np.testing.assert_array_equal(a.item(2, epoch=1)[0], b.item(2, epoch=1)[0])
    draws = {a.item(2, epoch=e)[0].tobytes() for e in range(4)}
    assert len(draws) > 1


def test_evaluation_input_does_not_depend_on_the_labels(fixture_dir, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(fixture_dir / "02", root / "02")
    ds = GraspDataset(find_samples(root), 112, augment=False)
    before = ds.item(0)[0]
    cpos = root / "02" / "pcd0003cpos.txt"
    far = GraspRectangle(150, 10, 0.0, 20, 10)  # near the right edge of the 160-px image
    cpos.write_text("".join(f"{x} {y}\n" for x, y in far.corners()))
    np.testing.assert_array_equal(ds.item(0)[0], before)
    assert not np.array_equal(GraspDataset(ds.samples, 112, augment=True).item(0)[0], before)
