"""train_ae reads ``lgdm sim grasp-data``'s sets: the grasp-image layout with every rectangle's
physics outcome in ``index.json``. The set comes from the Rust binary (``LGDM_BIN``, else
``<repo>/target/release/lgdm``; skipped without one): three scenes."""

from __future__ import annotations

import json
import subprocess

import pytest

from train_ae.data import (
    DatasetError,
    GraspDataset,
    find_samples,
    load_rectangles,
    read_grasp_index,
)


@pytest.fixture(scope="module")
def grasp_data_dir(tmp_path_factory, lgdm_binary):
    binary = lgdm_binary
    out = tmp_path_factory.mktemp("grasp-data") / "set"
    cmd = [str(binary), "sim", "grasp-data", "--out", str(out), "--scenes", "3", "--seed", "4",
           "--analytic", "3", "--random", "3", "--progress", "none"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, check=False)
    if r.returncode != 0:
        pytest.fail(f"{' '.join(cmd)} exited with {r.returncode}:\n{r.stderr[-2000:]}",
                    pytrace=False)
    return out


def test_a_grasp_data_set_loads_with_its_outcomes(grasp_data_dir):
    index = read_grasp_index(grasp_data_dir)
    assert index is not None and index.jaw_side_fraction is not None
    samples = find_samples(grasp_data_dir)
    assert samples
    tried = 0
    for s in samples:
        assert s.physics is not None and s.category is not None
        rects = load_rectangles(s)
        assert len(s.physics["positives"]) == len(rects.positives)
        assert len(s.physics["negatives"]) == len(rects.negatives)
        assert all(o["success"] for o in s.physics["positives"])
        assert not any(o["success"] for o in s.physics["negatives"])
        assert all(o["reason"] for o in s.physics["negatives"])
        tried += len(rects.positives) + len(rects.negatives)
    assert tried > 0
    # The images are network inputs like gen-dataset's.
    ds = GraspDataset(samples, 112, augment=True, seed=0)
    inputs, targets, _ = ds.item(0)
    assert inputs.shape == (4, 112, 112) and targets.shape == (5, 112, 112)
    # The failures reach the loss: the negative mask marks them.
    failed = next(i for i, s in enumerate(samples) if load_rectangles(s).negatives)
    assert ds.item(failed)[1][4].sum() > 0


def test_outcomes_that_do_not_match_the_rectangles_are_refused(grasp_data_dir, tmp_path):
    raw = json.loads((grasp_data_dir / "index.json").read_text())
    entry = next(e for e in raw["images"] if e["positives"] or e["negatives"])
    key = "positives" if entry["positives"] else "negatives"
    entry["physics"][key].pop()
    (tmp_path / "index.json").write_text(json.dumps(raw))
    with pytest.raises(DatasetError, match=f"physics.{key} has"):
        read_grasp_index(tmp_path)
