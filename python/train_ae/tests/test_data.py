"""The Cornell-layout loader (lgdm index.json, object map, folders), object-wise splits (per
category, fraction), the input resize, normalisation and augmentation consistency (square lgdm
crops: shift, flip, quarter turns; Cornell frames: zoom, quarter turns)."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from train_ae.data import (
    DatasetError,
    GraspDataset,
    Sample,
    find_samples,
    load_images,
    load_rectangles,
    normalize_rgbd,
    read_grasp_index,
    read_object_map,
    read_rectangles,
    resize_to_input,
    split_by_object,
    split_held_out_instances,
)
from train_ae.grasp import (
    GraspRectangle,
    angle_difference,
    decode_grasps,
    grasp_maps,
    is_correct,
)
from train_ae.synthetic import TABLE_DEPTH_M, write_synthetic_dataset


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
        np.testing.assert_array_equal(y[:4], np.stack(grasp_maps(rects, (112, 112))))


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


# --- lgdm crops: index.json (lgdm.grasp.v2), per-category hold-out, square-crop augmentation ----

def test_lgdm_index_gives_objects_categories_and_the_jaw(lgdm_dir):
    samples = find_samples(lgdm_dir)
    assert len(samples) == 12
    # gen-dataset numbering: image k is pcd(100 + k), object k mod 4, folders are not objects.
    assert [s.stem for s in samples[:2]] == ["pcd0100", "pcd0101"]
    assert [s.object_id for s in samples[:4]] == ["box_01", "bar_01", "box_02", "bar_02"]
    assert [s.category for s in samples[:4]] == ["box", "bar", "box", "bar"]
    index = read_grasp_index(lgdm_dir)
    assert index.jaw_side_fraction == pytest.approx(0.02 / 0.22)
    assert (index.crop_side_m, index.crop_size_px) == (0.22, 224)
    rgb, depth = load_images(samples[0])
    assert rgb.shape == (224, 224, 3) and depth.shape == (224, 224)
    (g,) = load_rectangles(samples[0]).positives
    assert g.jaw_px == pytest.approx(0.02 / 0.22 * 224, abs=0.01)


def test_old_list_index_and_no_index_load_as_before(tmp_path):
    for layout in ("list", "cornell"):
        root = write_synthetic_dataset(tmp_path / layout, objects=2, images_per_object=2,
                                       layout=layout)
        samples = find_samples(root)
        assert [s.object_id for s in samples] == ["01", "01", "02", "02"]
        assert all(s.category is None for s in samples)
        assert read_grasp_index(root) is None
        with pytest.raises(ValueError, match="no category"):
            split_held_out_instances(samples)


def test_object_map_overrides_the_index(lgdm_dir, tmp_path):
    m = tmp_path / "objects.txt"
    m.write_text("".join(f"pcd{100 + i:04d} obj{i % 3}\n" for i in range(12)))
    samples = find_samples(lgdm_dir, read_object_map(m))
    assert {s.object_id for s in samples} == {"obj0", "obj1", "obj2"}
    assert samples[1].category == "bar"


def test_bad_index_is_a_clear_error(lgdm_dir, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(lgdm_dir, root)
    index_path = root / "index.json"
    good = json.loads(index_path.read_text())
    index_path.write_text(json.dumps({**good, "format": "lgdm.grasp.v9"}))
    with pytest.raises(DatasetError, match=r"index\.json: format is 'lgdm.grasp.v9'"):
        find_samples(root)
    index_path.write_text(json.dumps({**good, "images": good["images"][1:]}))
    with pytest.raises(DatasetError, match=r"index\.json has no entry for 01/pcd0100"):
        find_samples(root)
    index_path.write_text(json.dumps({**good, "jaw_side_fraction": -1}))
    with pytest.raises(DatasetError, match="jaw_side_fraction must be a positive number"):
        find_samples(root)
    index_path.write_text("{not json")
    with pytest.raises(DatasetError, match="not readable JSON"):
        find_samples(root)
    index_path.write_text(json.dumps(good))
    (root / "01" / "pcd0100r.png").unlink()
    with pytest.raises(DatasetError, match=r"lists 1 image\(s\) not found.*pcd0100r\.png"):
        find_samples(root)


def test_index_without_a_crop_has_no_jaw_fraction(lgdm_dir, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(lgdm_dir, root)
    good = json.loads((root / "index.json").read_text())
    (root / "index.json").write_text(json.dumps({**good, "crop": None,
                                                 "jaw_side_fraction": None}))
    assert read_grasp_index(root).jaw_side_fraction is None
    assert find_samples(root)[0].object_id == "box_01"


def _fake_samples(spec):
    return [Sample(obj, Path(f"{obj}_{k}r.png"), Path("d"), Path("c"), category=cat)
            for cat, objs in spec.items() for obj in objs for k in range(2)]


def test_per_category_split_holds_out_one_instance_of_each_category():
    samples = _fake_samples({"mug": ["mug_1", "mug_2", "mug_3"], "can": ["can_1", "can_2"],
                             "vase": ["vase_1"]})
    train, held = split_held_out_instances(samples, per_category=1, seed=0)
    held_objs = {s.object_id for s in held}
    train_objs = {s.object_id for s in train}
    assert not held_objs & train_objs and len(train) + len(held) == len(samples)
    # One per category; a category with a single object keeps it for training.
    assert sorted(o.split("_")[0] for o in held_objs) == ["can", "mug"]
    assert "vase_1" in train_objs
    assert split_held_out_instances(samples, 1, seed=0) == (train, held)
    seen = {frozenset(s.object_id for s in split_held_out_instances(samples, 1, seed=k)[1])
            for k in range(10)}
    assert len(seen) > 1  # the seed chooses
    two = {s.object_id for s in split_held_out_instances(samples, 2, seed=0)[1]}
    assert len(two) == 3 and {"can_1", "can_2"} - two  # 2 mugs, 1 can (1 kept), no vase


def test_resize_to_input_area_averages_an_exact_factor_and_is_bilinear_otherwise():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 0.9, (8, 8)).astype(np.float32)
    depth[0, 0] = np.inf
    r4, d4 = resize_to_input(rgb, depth, 4)
    assert r4.shape == (4, 4, 3) and d4.shape == (4, 4) and r4.dtype == np.float32
    filled = np.where(np.isfinite(depth), depth, depth[np.isfinite(depth)].mean())
    np.testing.assert_allclose(d4, filled.reshape(4, 2, 4, 2).mean(axis=(1, 3)), rtol=1e-6)
    np.testing.assert_allclose(r4, rgb.astype(np.float32).reshape(4, 2, 4, 2, 3)
                               .mean(axis=(1, 3)), rtol=1e-6)
    r6, d6 = resize_to_input(rgb, depth, 6)
    assert r6.shape == (6, 6, 3) and np.isfinite(d6).all()
    r8, _ = resize_to_input(rgb, depth, 8)
    np.testing.assert_array_equal(r8, rgb.astype(np.float32))
    with pytest.raises(ValueError, match="square"):
        resize_to_input(rgb[:6], depth[:6], 4)


def test_square_crops_are_resized_whole_with_their_rectangles(lgdm_dir):
    samples = find_samples(lgdm_dir)
    ds = GraspDataset(samples, 112, augment=False)
    for i in range(len(samples)):
        x, _, (g,) = ds.item(i)
        raw = load_rectangles(samples[i]).positives[0]
        assert (g.center_x, g.center_y) == pytest.approx(
            ((raw.center_x + 0.5) / 2 - 0.5, (raw.center_y + 0.5) / 2 - 0.5), abs=1e-6)
        assert (g.width_px, g.jaw_px) == pytest.approx((raw.width_px / 2, raw.jaw_px / 2))
        assert x[0, round(g.center_y), round(g.center_x)] < -0.01  # on the box
        rgb, depth = load_images(samples[i])
        np.testing.assert_array_equal(x, normalize_rgbd(*resize_to_input(rgb, depth, 112)))
    with pytest.raises(ValueError, match="fixed scale"):
        ds.render(0, zoom=0.8)


@pytest.mark.parametrize("rot", [0, 1, 2, 3])
def test_flip_and_rotation_move_square_crops_and_labels_together(lgdm_dir, rot):
    ds = GraspDataset(find_samples(lgdm_dir), 112, augment=False)
    x0, y0, (r0,) = ds.render(1)
    x, y, (r,) = ds.render(1, rot90=rot, flip=True)
    # Whole-image transforms commute with 2x2 area averaging: flip, then rotate.
    expect_x = np.rot90(x0[:, :, ::-1], rot, axes=(1, 2))
    np.testing.assert_allclose(x, expect_x, atol=1e-6)
    np.testing.assert_array_equal(y[0], np.rot90(y0[0][:, ::-1], rot))
    # A flip mirrors the angle (θ -> -θ), each quarter turn adds 90° (modulo 180°).
    expect_angle = -r0.angle + rot * math.pi / 2
    assert angle_difference(r.angle, expect_angle) < 1e-9
    assert (r.width_px, r.jaw_px) == pytest.approx((r0.width_px, r0.jaw_px))
    np.testing.assert_allclose(y[1], np.rot90(y0[1][:, ::-1], rot) * (-1) ** rot, atol=1e-6)
    np.testing.assert_allclose(y[2], -np.rot90(y0[2][:, ::-1], rot) * (-1) ** rot, atol=1e-6)
    # The negative rectangle's mask moves with them.
    assert y0[4].sum() > 0
    np.testing.assert_array_equal(y[4], np.rot90(y0[4][:, ::-1], rot))
    # Decoding the transformed labels gives the transformed rectangle.
    (d,) = decode_grasps(*y[:4], jaw_px=r.jaw_px)
    assert is_correct(d, [r]) and angle_difference(d.angle, r.angle) < math.radians(1)


def test_shift_moves_square_crops_and_labels_together(lgdm_dir):
    ds = GraspDataset(find_samples(lgdm_dir), 112, augment=False)
    x0, y0, (r0,) = ds.render(2)
    x, y, (r,) = ds.render(2, shift=(6, -10))  # crop pixels: 3, -5 at 112
    assert (r.center_x - r0.center_x, r.center_y - r0.center_y) == pytest.approx((3, -5))
    np.testing.assert_array_equal(y[0][10:-10, 10:-10], np.roll(y0[0], (-5, 3), (0, 1))[10:-10,
                                                                                          10:-10])
    # Depth (before normalisation a constant offset) moves with the labels.
    d0 = x0[0] - x0[0].mean()
    d = x[0] - x[0].mean()
    inner = (slice(10, -10), slice(10, -10))
    np.testing.assert_allclose(d[inner] - np.roll(d0, (-5, 3), (0, 1))[inner],
                               (d[inner] - np.roll(d0, (-5, 3), (0, 1))[inner]).mean(),
                               atol=1e-5)


def test_square_augmentation_draws_rotation_flip_and_shift_only(lgdm_dir):
    samples = find_samples(lgdm_dir)
    ds = GraspDataset(samples, 112, augment=True, seed=3)
    ref = GraspDataset(samples, 112, augment=False)
    _, _, (r0,) = ref.item(0)
    widths, angles = set(), set()
    for e in range(12):
        x, y, (r,) = ds.item(0, epoch=e)
        np.testing.assert_array_equal(y[:4], np.stack(grasp_maps([r], (112, 112))))
        widths.add(round(r.width_px, 6))
        angles.add(round(angle_difference(r.angle, r0.angle), 6))
        assert x[0, round(r.center_y), round(r.center_x)] < -0.01  # still on the box
    assert widths == {round(r0.width_px, 6)}  # no zoom
    assert len(angles) > 1
    np.testing.assert_array_equal(ds.item(0, epoch=5)[0], ds.item(0, epoch=5)[0])
