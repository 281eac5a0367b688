"""The shipped default checkpoint: bridge.default_checkpoint() names a loadable `cpu` model
whose maps and features have the bridge's shapes; a missing file is a clear FileNotFoundError.
The checkpoint is part of the repository, so its absence fails the test rather than skipping it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from train_ae import bridge
from train_ae.checkpoint import FORMAT, load_checkpoint
from train_ae.grasp import wilson_interval
from train_ae.model import FEATURE_DIM


def test_missing_default_checkpoint_raises_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setattr(bridge, "DEFAULT_CHECKPOINT", tmp_path / "weights" / "cpu.pt")
    with pytest.raises(FileNotFoundError, match="default train_ae checkpoint"):
        bridge.default_checkpoint()


def test_default_checkpoint_loads_as_the_cpu_configuration():
    # weights/cpu.pt is tracked in git and is package data: absent is a failure, not a skip.
    path = bridge.default_checkpoint()
    assert Path(path).is_absolute()
    model, ckpt = load_checkpoint(path)
    assert ckpt["format"] == FORMAT
    assert model.config.name == "cpu"
    assert bridge.input_size(model) == 112
    heldout = ckpt["metrics"]["heldout"]
    # A trained network: its recorded held-out rectangle metric (382/480 = 79.6 % when it was
    # made) is far above what an untrained one scores, with that count's Wilson interval.
    n, correct = heldout["n"], heldout["correct"]
    assert n >= 100 and correct / n >= 0.5, heldout
    assert heldout["accuracy"] == correct / n
    assert heldout["ci95"] == pytest.approx(wilson_interval(correct, n), abs=1e-12)
    # Trained on object-centred crops: decodes with the finger-width jaw, and held out one
    # whole instance of each of the ten categories.
    assert model.config.jaw_side_fraction == pytest.approx(0.02 / 0.22, rel=1e-6)
    cats = {o.rsplit("_", 1)[0] for o in heldout["objects"]}
    assert len(heldout["objects"]) == len(cats) == 10

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


def _fake_lgdm(tmp_path: Path) -> Path:
    """A stand-in lgdm: ``gen-dataset`` writes the synthetic lgdm-layout fixture under
    OUT/grasp, ``sim grasp-data`` writes one into OUT, ``sim objects`` makes OUT."""
    import sys

    fake = tmp_path / "lgdm"
    src = Path(__file__).resolve().parents[1] / "src"
    fake.write_text(
        f"#!{sys.executable}\n"
        "import os, sys\n"
        f"sys.path.insert(0, {str(src)!r})\n"
        "from train_ae.synthetic import write_synthetic_dataset\n"
        "out = sys.argv[sys.argv.index('--out') + 1]\n"
        "if 'objects' in sys.argv:\n"
        "    os.makedirs(out)\n"
        "else:\n"
        "    write_synthetic_dataset(out + ('/grasp' if 'gen-dataset' in sys.argv else ''),\n"
        "                            objects=4, images_per_object=2, layout='lgdm',\n"
        "                            categories=2)\n")
    fake.chmod(0o755)
    return fake


def test_make_default_runs_gen_dataset_then_train(tmp_path, capsys):
    """The geometric stage alone (``--geometric-only``) with a stand-in lgdm."""
    from train_ae import make_default

    fake = _fake_lgdm(tmp_path)
    out = tmp_path / "ckpt.pt"
    assert make_default.main(["--lgdm", str(fake), "--work", str(tmp_path / "w"), "--out",
                              str(out), "--epochs", "1", "--images", "8", "--quiet",
                              "--geometric-only"]) == 0
    err = capsys.readouterr().err
    assert (f"$ {fake} gen-dataset --preset paper --frames 1 --grasp-images 8 --seed 0 "
            f"--out {tmp_path / 'w' / 'data'} --progress none") in err
    assert "--holdout per-category" in err and "held out (per-category)" in err
    assert "grasp-data" not in err
    _, ckpt = load_checkpoint(out)
    assert ckpt["config"]["jaw_side_fraction"] == pytest.approx(0.02 / 0.22)


def test_make_default_fine_tunes_on_the_robots_data(tmp_path, capsys):
    """Both stages: the robot's data (procedural, then the YCB meshes but the paper's), and a
    fine-tune of the geometric checkpoint on the three sets that holds out what it held out."""
    from train_ae import make_default

    fake = _fake_lgdm(tmp_path)
    work, out = tmp_path / "w", tmp_path / "ckpt.pt"
    argv = ["--lgdm", str(fake), "--work", str(work), "--out", str(out), "--epochs", "1",
            "--images", "8", "--robot-scenes", "5", "--ycb-scenes", "3", "--finetune-epochs",
            "1", "--quiet"]
    assert make_default.main(argv) == 0
    err = capsys.readouterr().err
    for line in (f"$ {fake} sim grasp-data --out {work / 'robot'} --scenes 5 --seed 0 "
                 f"--instances 10 --rim 0 --progress none",
                 f"$ {fake} sim objects --set others --out {work / 'ycb-others'}",
                 f"$ {fake} sim grasp-data --out {work / 'robot-ycb'} --meshes "
                 f"{work / 'ycb-others'} --scenes 3 --seed 2 --rim 0 --progress none",
                 f"--init {work / 'geometric' / 'cpu.pt'} --epochs 1 --neg-weight 10 "):
        assert line in err, line
    geometric = load_checkpoint(work / "geometric" / "cpu.pt")[1]["metrics"]
    tuned = load_checkpoint(out)[1]["metrics"]
    assert tuned["training"]["data"] == [str(work / "robot"), str(work / "data" / "grasp"),
                                         str(work / "robot-ycb")]
    assert tuned["training"]["init"]["file"] == "cpu.pt"
    # The fine-tune weighs the robot's failed grasps; the geometric stage does not.
    assert (geometric["training"]["neg_weight"], tuned["training"]["neg_weight"]) == (1, 10)
    assert tuned["heldout"]["objects"] == geometric["heldout"]["objects"]
    # --skip-data reuses every data directory; --init replaces the geometric stage.
    assert make_default.main([*argv, "--skip-data", "--init", str(out),
                              "--out", str(tmp_path / "again.pt")]) == 0
    err = capsys.readouterr().err
    assert err.count("skipped") == 4 and "step 2" not in err
    with pytest.raises(SystemExit) as e:
        make_default.main([*argv, "--init", str(tmp_path / "none.pt")])
    assert e.value.code == 2 and "none.pt does not exist" in capsys.readouterr().err


def test_make_default_adds_generator_seeds_and_repeats_the_robots_images(tmp_path, capsys):
    """--more-seeds K adds gen-dataset runs of seeds S+1..S+K to the fine-tune's data;
    --robot-repeat R shows the robot's two sets R times per epoch (train_ae --repeat)."""
    from train_ae import make_default

    fake = _fake_lgdm(tmp_path)
    work, out = tmp_path / "w", tmp_path / "ckpt.pt"
    argv = ["--lgdm", str(fake), "--work", str(work), "--out", str(out), "--epochs", "1",
            "--images", "8", "--robot-scenes", "5", "--ycb-scenes", "3", "--finetune-epochs",
            "1", "--quiet", "--seed", "3", "--more-seeds", "2", "--more-images", "6",
            "--robot-repeat", "2"]
    assert make_default.main(argv) == 0
    err = capsys.readouterr().err
    for seed in (4, 5):
        assert (f"$ {fake} gen-dataset --preset paper --frames 1 --grasp-images 6 --seed {seed} "
                f"--out {work / f'data-seed{seed}'} --progress none") in err
    t = load_checkpoint(out)[1]["metrics"]["training"]
    assert t["data"] == [str(work / "robot"), str(work / "data" / "grasp"),
                         str(work / "robot-ycb"), str(work / "data-seed4" / "grasp"),
                         str(work / "data-seed5" / "grasp")]
    assert t["repeat"] == {str(work / "robot"): 2, str(work / "robot-ycb"): 2}
    assert make_default.main([*argv, "--skip-data", "--init", str(out),
                              "--out", str(tmp_path / "again.pt")]) == 0
    assert capsys.readouterr().err.count("skipped") == 6
    for bad in (["--more-seeds", "-1"], ["--robot-repeat", "0"], ["--more-images", "0"]):
        with pytest.raises(SystemExit) as e:
            make_default.main([*argv, *bad])
        assert e.value.code == 2
    # Seeds S+5..S+7 are the validation and test families: never trained on.
    with pytest.raises(SystemExit):
        make_default.main([*argv, "--more-seeds", "5", "--out", str(tmp_path / "x.pt")])
    assert "would train on generator seed(s) [8]" in capsys.readouterr().err
    assert not (tmp_path / "x.pt").exists()
    # --input-size reaches step 5.
    assert make_default.main([*argv, "--skip-data", "--init", str(out), "--input-size", "224",
                              "--out", str(tmp_path / "big.pt")]) == 0
    assert "--input-size 224" in capsys.readouterr().err
    assert load_checkpoint(tmp_path / "big.pt")[0].config.input_size == 224
    assert make_default.main([*argv, "--skip-data", "--init", str(out), "--balance-images",
                              "--out", str(tmp_path / "bal.pt")]) == 0
    assert "--balance-images" in capsys.readouterr().err
    assert load_checkpoint(tmp_path / "bal.pt")[1]["metrics"]["training"]["balance_images"]
