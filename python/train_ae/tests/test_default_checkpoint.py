"""The shipped default checkpoint: bridge.default_checkpoint() names a loadable `cpu` model
whose maps and features have the bridge's shapes; a missing file is a clear FileNotFoundError."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from train_ae import bridge
from train_ae.checkpoint import FORMAT, load_checkpoint
from train_ae.model import FEATURE_DIM

SHIPPED = bridge.DEFAULT_CHECKPOINT.is_file()


def test_missing_default_checkpoint_raises_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setattr(bridge, "DEFAULT_CHECKPOINT", tmp_path / "weights" / "cpu.pt")
    with pytest.raises(FileNotFoundError, match="default train_ae checkpoint"):
        bridge.default_checkpoint()


@pytest.mark.skipif(not SHIPPED, reason="weights/cpu.pt not present in this checkout")
def test_default_checkpoint_loads_as_the_cpu_configuration():
    path = bridge.default_checkpoint()
    assert Path(path).is_absolute()
    model, ckpt = load_checkpoint(path)
    assert ckpt["format"] == FORMAT
    assert model.config.name == "cpu"
    assert bridge.input_size(model) == 112
    heldout = ckpt["metrics"]["heldout"]
    assert heldout["n"] > 0 and 0 <= heldout["correct"] <= heldout["n"]

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (112, 112, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 0.7, (112, 112)).astype(np.float32)
    x = np.stack([bridge.preprocess(rgb, depth)] * 2)
    features, q, c, s, w = bridge.infer(bridge.load(path), x)
    assert features.shape == (2, FEATURE_DIM)
    np.testing.assert_allclose(np.linalg.norm(features, axis=1), 1.0, atol=1e-5)
    for m in (q, c, s, w):
        assert m.shape == (2, 112, 112) and m.dtype == np.float32
        assert np.isfinite(m).all()


def test_object_map_from_a_gen_dataset_index(tmp_path):
    import json

    from train_ae.data import read_object_map
    from train_ae.make_default import write_object_map

    index = tmp_path / "index.json"
    index.write_text(json.dumps([
        {"number": 100, "prefix": "01/pcd0100", "object": "mug_01"},
        {"number": 101, "prefix": "01/pcd0101", "object": "mug_02"},
        {"number": 200, "prefix": "02/pcd0200", "object": "mug_01"},
    ]))
    out = tmp_path / "objects.txt"
    assert write_object_map(index, out) == 3
    assert read_object_map(out) == {"pcd0100": "mug_01", "pcd0101": "mug_02",
                                    "pcd0200": "mug_01"}
