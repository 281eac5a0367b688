"""Packs (``train_ae.pack``) and the GPU trainer (``train_ae.gpu``), run on the CPU: a pack
gives back the directory's images and rectangles, the trainer's on-device inputs and targets
are ``GraspDataset.render``'s transform by transform, a too-large pack is refused, the same
inputs give the same bytes, and a tiny budget leaves loadable checkpoints and a record."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from train_ae import bridge
from train_ae import evaluate as evaluate_cli
from train_ae import pack as pack_cli
from train_ae.checkpoint import load_checkpoint
from train_ae.data import GraspDataset, find_samples, load_images, load_rectangles
from train_ae.gpu import DeviceImages, label_canvases
from train_ae.gpu import __main__ as gpu_cli
from train_ae.pack import PackedGraspDataset, read_pack
from train_ae.synthetic import write_synthetic_dataset


@pytest.fixture(scope="module")
def two_dirs(tmp_path_factory):
    """Two lgdm-layout sets (the second with NaN depth pixels), as gen-dataset's ``grasp/``."""
    root = tmp_path_factory.mktemp("packsrc")
    a = write_synthetic_dataset(root / "gen-a" / "grasp", objects=4, images_per_object=2,
                                seed=1, categories=2)
    b = write_synthetic_dataset(root / "phys-b", objects=3, images_per_object=2, seed=2,
                                categories=3)
    from PIL import Image
    for tiff in sorted(b.glob("*/*d.tiff"))[:2]:
        d = np.asarray(Image.open(tiff), dtype=np.float32).copy()
        d[5:9, 30:60] = np.nan
        Image.fromarray(d).save(tiff)
    (root / "gen-a" / "manifest.json").write_text(json.dumps({"seed": 11, "preset": "x"}))
    return [a, b]


@pytest.fixture(scope="module")
def packed(two_dirs, tmp_path_factory):
    out = tmp_path_factory.mktemp("pack") / "p.npz"
    assert pack_cli.main(["--data", str(two_dirs[0]), "--data", str(two_dirs[1]),
                          "--out", str(out), "--quiet"]) == 0
    return out


def test_pack_round_trip(two_dirs, packed):
    pk = read_pack(packed)
    samples = find_samples(two_dirs[0]) + find_samples(two_dirs[1])
    assert len(pk) == len(samples) == 14
    names = [d["name"] for d in pk.manifest["datasets"]]
    assert names == ["gen-a/grasp", "phys-b"]
    assert pk.manifest["datasets"][0]["seed"] == 11
    assert [d["images"] for d in pk.manifest["datasets"]] == [8, 6]
    for i, s in enumerate(samples):
        rgb, depth = load_images(s)
        np.testing.assert_array_equal(pk.rgb[i], rgb)
        ok = np.isfinite(depth)
        np.testing.assert_array_equal(np.isfinite(pk.depth[i]), ok)
        assert np.abs(pk.depth[i][ok] - depth[ok]).max() <= pack_cli.DEPTH_STEP_M / 2 + 1e-6
        labels = load_rectangles(s)
        assert pk.positives[i] == labels.positives  # the very same float64 rectangles
        assert pk.negatives[i] == labels.negatives
        assert (pk.samples[i].object_id, pk.samples[i].category) == (s.object_id, s.category)
    # The evaluation path: the directory loader's own rendering of the pack's arrays.
    ds_dir = GraspDataset(samples, 112, augment=False)
    ds_pack = PackedGraspDataset([pk], [(0, i) for i in range(len(pk))], 112)
    for i in (0, 9):
        x0, y0, r0 = ds_dir.item(i)
        x1, y1, r1 = ds_pack.item(i)
        np.testing.assert_array_equal(y0, y1)
        assert r0 == r1
        np.testing.assert_allclose(x0, x1, atol=1e-4)


@pytest.mark.parametrize("size", [224, 112])
def test_device_batches_are_the_loaders(two_dirs, packed, size):
    """Inputs and targets of the on-device augmentation equal ``GraspDataset.render``'s for
    every kind of transform, at the crop's size and at half of it."""
    pk = read_pack(packed)
    samples = find_samples(two_dirs[0]) + find_samples(two_dirs[1])
    ds = GraspDataset(samples, size, augment=True)
    data = DeviceImages([pk], torch.device("cpu"), [size])
    cases = [(0, 0, 0, 0, 0), (9, 1, 0, 0, 0), (3, 0, 1, 0, 0), (10, 2, 1, 5, -3),
             (11, 3, 0, -16, 16), (5, 1, 1, 7, 2), (12, 3, 1, -1, -9), (13, 0, 0, 16, -16)]
    idx = torch.tensor([c[0] for c in cases])
    rot = torch.tensor([c[1] for c in cases])
    flip = torch.tensor([c[2] for c in cases])
    shift = torch.tensor([[c[3], c[4]] for c in cases])
    x, y = data.batch(idx, rot, flip, shift, [size])[size]
    for j, (i, r, f, dx, dy) in enumerate(cases):
        x0, y0, _ = ds.render(i, rot90=r, flip=bool(f), shift=(dx, dy))
        np.testing.assert_allclose(y[j].numpy(), y0, atol=1e-6, err_msg=str(cases[j]))
        np.testing.assert_allclose(x[j].numpy(), x0, atol=2e-4, err_msg=str(cases[j]))


def test_canvas_workers_agree(packed):
    pk = read_pack(packed)
    from train_ae.gpu import CanvasGeometry
    g = CanvasGeometry(224, 112)
    pos, neg = pk.positives * 5, pk.negatives * 5  # > 64 images: the forked path
    one = label_canvases(pos, neg, g, workers=1)
    two = label_canvases(pos, neg, g, workers=2)
    np.testing.assert_array_equal(one, two)


def test_pack_is_deterministic(two_dirs, packed, tmp_path):
    again = tmp_path / "again.npz"
    assert pack_cli.main(["--data", str(two_dirs[0]), "--data", str(two_dirs[1]),
                          "--out", str(again), "--quiet"]) == 0
    assert again.read_bytes() == packed.read_bytes()


def test_pack_refuses_a_size_over_the_limit(two_dirs, tmp_path, capsys):
    out = tmp_path / "big.npz"
    assert pack_cli.main(["--data", str(two_dirs[0]), "--out", str(out),
                          "--max-mib", "0.01", "--quiet"]) == 2
    assert "more than --max-mib" in capsys.readouterr().err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_pack_at_a_smaller_size(two_dirs, tmp_path):
    out = tmp_path / "small.npz"
    assert pack_cli.main(["--data", str(two_dirs[0]), "--out", str(out), "--size", "112",
                          "--quiet"]) == 0
    pk = read_pack(out)
    assert pk.size == 112 and pk.rgb.shape[1:] == (112, 112, 3)
    r = find_samples(two_dirs[0])[0]
    full = load_rectangles(r).positives[0]
    assert abs(pk.positives[0][0].width_px - full.width_px / 2) < 1e-9


def test_gpu_trainer_on_the_cpu(packed, two_dirs, tmp_path):
    """A tiny budget on the CPU: both checkpoints load with the bridge and the evaluate
    command, the record says how they were made."""
    out = tmp_path / "run"
    commit = tmp_path / "commit.txt"
    commit.write_text("abc123\n")
    argv = ["--pack", str(packed), "--config", "cpu", "--minutes", "1.5", "--out", str(out),
            "--distill", "cpu", "--batch-size", "4", "--distill-batch-size", "4",
            "--max-steps", "3", "--save-every", "0", "--commit-file", str(commit),
            "--device", "cpu", "--workers", "1", "--repeat", "phys-b=2"]
    assert gpu_cli.main(argv) == 0
    record = json.loads((out / "record.json").read_text())
    assert record["commit"] == "abc123"
    assert record["packs"][0]["sha256"] and record["packs"][0]["manifest"]["images"] == 14
    assert set(record["outputs"]) == {"cpu.pt", "cpu-distilled.pt"}
    for name in ("cpu", "cpu-distilled"):
        phase = record["phases"][name]
        assert phase["steps"] == 3 and phase["stopped"] == "max_steps"
        assert phase["heldout"]["n"] >= 1
        model = bridge.load(str(out / f"{name}.pt"))
        assert bridge.input_size(model) == 112
        _, ckpt = load_checkpoint(out / f"{name}.pt")
        assert ckpt["metrics"]["heldout"]["objects"] == record["split"]["held_out_objects"]
        assert ckpt["metrics"]["training"]["trainer"] == "train_ae.gpu"
    held = record["split"]["held_out_objects"]
    assert held and record["split"]["train_images"] > 0
    assert evaluate_cli.main(["--data", str(two_dirs[0]), "--ckpt", str(out / "cpu.pt"),
                              "--all", "--quiet"]) == 0
    assert not list(out.glob("*.tmp")) and not list(out.glob(".*"))


def test_gpu_trainer_refuses_a_budget_too_small(packed, tmp_path, capsys):
    argv = ["--pack", str(packed), "--config", "cpu", "--minutes", "0.001", "--out",
            str(tmp_path / "r"), "--device", "cpu", "--workers", "1"]
    assert gpu_cli.main(argv) == 2
    assert "leaves" in capsys.readouterr().err


def test_gpu_trainer_keeps_its_checkpoints_when_evaluation_fails(packed, tmp_path,
                                                                 monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("decoder exploded")

    monkeypatch.setattr(gpu_cli, "evaluate_model", broken)
    out = tmp_path / "run"
    argv = ["--pack", str(packed), "--config", "cpu", "--minutes", "1", "--out", str(out),
            "--distill", "cpu", "--batch-size", "4", "--distill-batch-size", "4",
            "--max-steps", "1", "--device", "cpu", "--workers", "1"]
    assert gpu_cli.main(argv) == 0
    record = json.loads((out / "record.json").read_text())
    assert set(record["outputs"]) == {"cpu.pt", "cpu-distilled.pt"}
    assert "decoder exploded" in record["phases"]["cpu"]["heldout"]["error"]
    assert bridge.input_size(bridge.load(str(out / "cpu-distilled.pt"))) == 112


def test_the_kept_gpu_run_is_what_its_record_says():
    """``gpu-runs/2026-12-04``: the student's bytes are the ones its record names, and it loads
    as a `cpu` network the bridge runs."""
    import hashlib
    import json
    from pathlib import Path

    import torch

    from train_ae import bridge

    run = Path(__file__).resolve().parents[1] / "gpu-runs" / "2026-12-04"
    record = json.loads((run / "record.json").read_text())
    student = run / "cpu-distilled.pt"
    assert hashlib.sha256(student.read_bytes()).hexdigest() == record["outputs"][student.name]
    assert record["machine"]["gpu"] == "NVIDIA H200"
    net = bridge.load(student)
    with torch.no_grad():
        out = net(torch.zeros(1, 4, 112, 112))
    assert len(out) >= 4
