"""The ceiling of the rectangle metric on lgdm's own data: the training targets (label maps) of
every evaluation input, decoded with the dataset's jaw, must score (nearly) every image. If they
do not, no network can, and the crop, the resize, the labels or the decoder is wrong.

The dataset comes from the Rust binary (``LGDM_BIN``, else ``<repo>/target/release/lgdm``):
``lgdm gen-dataset --preset small --frames 1 --grasp-images 60 --seed 0``. Without a binary the
test is skipped; a ``LGDM_BIN`` that does not exist is a failure. The rim round trip below needs
no binary.
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import pytest

from train_ae.data import GraspDataset, find_samples, read_grasp_index
from train_ae.grasp import (
    GraspRectangle,
    angle_difference,
    decode_grasps,
    grasp_maps,
    is_correct,
    jaw_px_for,
    rectangle_iou,
)

REPO = Path(__file__).resolve().parents[3]
INPUT_SIZE = 112
"""The ``cpu`` configuration's input side."""
MIN_IMAGES = 40
MIN_ACCURACY = 0.99


@pytest.fixture(scope="module")
def lgdm_grasp_dir(tmp_path_factory, lgdm_binary) -> Path:
    binary = lgdm_binary
    out = tmp_path_factory.mktemp("ceiling") / "ds"
    cmd = [str(binary), "gen-dataset", "--preset", "small", "--frames", "1", "--grasp-images",
           "60", "--seed", "0", "--out", str(out), "--progress", "none"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, check=False)
    if r.returncode != 0:
        pytest.fail(f"{' '.join(cmd)} exited with {r.returncode}:\n{r.stderr[-2000:]}",
                    pytrace=False)
    return out / "grasp"


def test_ground_truth_maps_score_every_lgdm_image(lgdm_grasp_dir):
    index = read_grasp_index(lgdm_grasp_dir)
    assert index is not None, (f"{lgdm_grasp_dir}/index.json is not the object form "
                               f"lgdm.grasp.v2: the lgdm binary predates the crops")
    assert index.jaw_side_fraction is not None, "index.json has no jaw_side_fraction (no crop)"
    samples = find_samples(lgdm_grasp_dir)
    assert all(s.category is not None for s in samples)
    jaw = jaw_px_for(index.jaw_side_fraction, INPUT_SIZE)
    # The evaluation inputs, and (same check) one epoch of augmented training items.
    for augment in (False, True):
        ds = GraspDataset(samples, INPUT_SIZE, augment=augment, seed=0)
        n = correct = 0
        failures = []
        for i in range(len(ds)):
            _, targets, rects = ds.item(i, epoch=0)
            if not rects:
                continue
            n += 1
            pred = decode_grasps(*targets[:4], num_grasps=1, jaw_px=jaw)
            if pred and is_correct(pred[0], rects):
                correct += 1
            else:
                failures.append(f"{samples[i].rgb_path.name} ({samples[i].object_id}): "
                                f"{pred[0] if pred else 'no grasp'}")
        print(f"ground-truth ceiling (augment {augment}): {correct}/{n} with jaw {jaw:.2f} px "
              f"at {INPUT_SIZE} px")
        assert n >= MIN_IMAGES, f"only {n} images with positive rectangles"
        assert correct >= MIN_ACCURACY * n, (f"augment {augment}: {correct}/{n}; failures: "
                                             f"{failures[:5]}")


@pytest.mark.parametrize("angle_deg", [90.0, 89.0, -89.0, 87.0, -86.0, 45.0])
def test_rim_pinch_round_trip(angle_deg):
    """A thin rim pinch (4 px opening, 10 px jaw) -> label maps -> decode: correct with the
    real jaw; opening / 2 would give a 4 x 2 rectangle with IoU 0.2."""
    gt = GraspRectangle(31.3, 30.6, math.radians(angle_deg), 4.0, 10.0)
    gt = GraspRectangle.from_corners(gt.corners())
    maps = grasp_maps([gt], (64, 64))
    assert maps[0].sum() > 0
    (pred,) = decode_grasps(*maps, num_grasps=1, jaw_px=10.0)
    assert angle_difference(pred.angle, gt.angle) <= math.radians(30), (pred, gt)
    assert rectangle_iou(pred, gt) > 0.25, (pred, gt, rectangle_iou(pred, gt))
    assert is_correct(pred, [gt])
