"""Training lowers the loss, is seeded and deterministic; checkpoints round-trip with
weights_only=True; the CLIs run end to end; the bridge functions keep their contract."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import torch
from conftest import wilson_case

from train_ae import bridge
from train_ae import evaluate as evaluate_cli
from train_ae import train as train_cli
from train_ae.checkpoint import FORMAT, load_checkpoint, save_checkpoint
from train_ae.data import GraspDataset, find_samples, load_images, normalize_rgbd
from train_ae.model import GraspAutoencoder, ModelConfig
from train_ae.synthetic import write_synthetic_dataset
from train_ae.training import (
    LABEL_COUNT_BINS,
    evaluate_model,
    format_result,
    grasp_loss,
    train_model,
)


def _model(seed=0):
    torch.manual_seed(seed)
    return GraspAutoencoder(ModelConfig.preset("cpu"))


def test_a_few_steps_lower_the_loss(fixture_dir):
    ds = GraspDataset(find_samples(fixture_dir)[:4], 112, augment=False)
    model = _model()
    x, y, _ = ds.batch(list(range(4)))

    def loss_now():
        model.train()
        with torch.no_grad():
            return float(grasp_loss(model(x), y))

    before = loss_now()
    hist = train_model(model, ds, epochs=12, batch_size=4, lr=1e-3, seed=0)
    after = loss_now()
    assert hist.images == 48 and len(hist.epoch_loss) == 12
    print(f"loss on a fixed batch: {before:.4f} -> {after:.4f}")
    assert after < 0.5 * before, (before, after)
    assert hist.epoch_loss[-1] < hist.epoch_loss[0]


def test_same_seed_same_weights(fixture_dir):
    tiny = ModelConfig(name="tiny", input_size=48, channels=8, encoder_res_blocks=1,
                       bottleneck_res_blocks=1)
    ds = GraspDataset(find_samples(fixture_dir)[:6], tiny.input_size, augment=True, seed=1)
    states = []
    for _ in range(2):
        torch.manual_seed(7)
        model = GraspAutoencoder(tiny)
        train_model(model, ds, epochs=2, batch_size=3, seed=1)
        states.append(model.state_dict())
    for k in states[0]:
        assert torch.equal(states[0][k], states[1][k]), k


def test_checkpoint_round_trip_with_weights_only(fixture_dir, tmp_path):
    ds = GraspDataset(find_samples(fixture_dir)[:4], 112, augment=False)
    model = _model()
    train_model(model, ds, epochs=1, batch_size=4, max_steps=1)  # non-trivial BN statistics
    model.eval()
    path = tmp_path / "ae.pt"
    save_checkpoint(path, model, {"heldout": {"n": 3, "objects": ["02"]}})
    raw = torch.load(path, weights_only=True)
    assert raw["format"] == FORMAT and raw["config"] == model.config.to_dict()
    assert not (tmp_path / "ae.pt.tmp").exists()
    loaded, ckpt = load_checkpoint(path)
    assert not loaded.training
    assert ckpt["metrics"]["heldout"]["objects"] == ["02"]
    x, _, _ = ds.batch([0, 1])
    with torch.inference_mode():
        fa, ma = model.forward_with_features(x)
        fb, mb = loaded.forward_with_features(x)
    assert torch.equal(fa, fb)
    for a, b in zip(ma, mb, strict=True):
        assert torch.equal(a, b)


def test_not_a_checkpoint_is_a_clear_error(tmp_path):
    p = tmp_path / "x.pt"
    p.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a readable train_ae checkpoint"):
        load_checkpoint(p)
    torch.save({"state_dict": {}}, p)
    with pytest.raises(ValueError, match="format key"):
        load_checkpoint(p)


def test_train_and_evaluate_commands(fixture_dir, tmp_path, capsys, wilson_cases):
    out = tmp_path / "run" / "ae.pt"
    argv = ["--data", str(fixture_dir), "--config", "cpu", "--epochs", "1", "--out", str(out),
            "--batch-size", "4", "--val-fraction", "0.25", "--seed", "3", "--threads", "1",
            "--quiet"]
    assert train_cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "held-out objects, final epoch 1: rectangle metric" in err and "n = 3" in err
    _, ckpt = load_checkpoint(out)
    held = ckpt["metrics"]["heldout"]
    assert held["n"] == 3 and len(held["objects"]) == 1
    # The recorded interval is the Wilson interval of the recorded counts (the shared fixture,
    # computed with the Rust formula, has every k/3).
    assert 0 <= held["correct"] <= 3
    assert held["ci95"] == pytest.approx(wilson_case(wilson_cases, held["correct"], 3), abs=1e-12)
    assert set(ckpt["metrics"]["training"]["train_objects"]).isdisjoint(held["objects"])

    assert evaluate_cli.main(["--data", str(fixture_dir), "--ckpt", str(out), "--threads", "1",
                              "--quiet"]) == 0
    assert "n = 3" in capsys.readouterr().err
    assert evaluate_cli.main(["--data", str(fixture_dir), "--ckpt", str(out), "--all",
                              "--threads", "1", "--quiet"]) == 0
    assert "4 objects" in capsys.readouterr().err
    assert train_cli.main([*argv[:1], str(tmp_path / "missing"), *argv[2:]]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_evaluation_of_perfect_maps_scores_everything(fixture_dir, wilson_cases):
    """The metric pipeline itself, with a stand-in network that returns the label maps."""
    ds = GraspDataset(find_samples(fixture_dir), 112, augment=False)
    targets = [torch.from_numpy(ds.item(i)[1]) for i in range(len(ds))]

    class Oracle(torch.nn.Module):
        seen = 0

        def forward(self, x):
            y = torch.stack(targets[self.seen:self.seen + len(x)])
            self.seen += len(x)
            return tuple(y[:, k] for k in range(4))

    result = evaluate_model(Oracle(), ds, batch_size=5)
    assert result["n"] == len(ds) == result["correct"] == 12
    assert result["ci95"] == list(wilson_case(wilson_cases, 12, 12))  # high exactly 1.0
    assert result["ci95"][1] == 1.0


def test_bridge_contract(fixture_dir, tmp_path):
    model = _model()
    path = tmp_path / "ae.pt"
    save_checkpoint(path, model.eval(), {})
    m = bridge.load(path)
    assert bridge.input_size(m) == 112
    rgb = np.zeros((112, 112, 3), np.uint8)
    rgb[30:60, 40:80] = (200, 40, 40)
    depth = np.full((112, 112), 0.7, np.float32)
    depth[30:60, 40:80] = 0.65
    x = bridge.preprocess(rgb, depth)
    assert x.shape == (4, 112, 112) and x.dtype == np.float32 and x.flags.c_contiguous
    np.testing.assert_array_equal(x, normalize_rgbd(rgb, depth))
    batch = np.stack([x, x[:, ::-1, :]])
    features, q, c, s, w = bridge.infer(m, batch)
    assert features.shape == (2, 256) and features.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(features, axis=1), 1.0, atol=1e-5)
    for a in (q, c, s, w):
        assert a.shape == (2, 112, 112) and a.dtype == np.float32
    # Same as running the model directly.
    with torch.inference_mode():
        f2, maps = m.forward_with_features(torch.from_numpy(batch.copy()))
    np.testing.assert_array_equal(features, f2.numpy())
    np.testing.assert_array_equal(w, maps.width.numpy())
    with pytest.raises(ValueError, match="uint8"):
        bridge.preprocess(rgb.astype(np.float32), depth)
    with pytest.raises(ValueError, match=r"\(N, 4, H, W\)"):
        bridge.infer(m, x)
    with pytest.raises(ValueError, match="NaN"):
        bridge.infer(m, np.full((1, 4, 112, 112), np.nan, np.float32))


def test_bridge_preprocess_matches_training_input(tmp_path):
    """At the model's input size, crop and resize are the identity: same input as training."""
    root = write_synthetic_dataset(tmp_path, objects=1, images_per_object=1, width=112,
                                   height=112)
    (s,) = find_samples(root)
    rgb, depth = load_images(s)
    ds = GraspDataset([s], 112, augment=False)
    np.testing.assert_allclose(bridge.preprocess(rgb, depth), ds.item(0)[0], atol=1e-6)


def test_weighted_loss_weights_positives_in_all_four_terms():
    torch.manual_seed(0)
    targets = torch.zeros(2, 4, 8, 8)
    targets[0, :, 2, 3] = torch.tensor([1.0, 0.5, -0.5, 0.2])
    targets[1, :, 5, 5] = torch.tensor([1.0, -1.0, 0.0, 0.4])
    maps = tuple(torch.randn(2, 8, 8) for _ in range(4))
    paper = grasp_loss(maps, targets, "paper")
    assert float(paper) == pytest.approx(
        sum(float(torch.nn.functional.smooth_l1_loss(m, targets[:, i]))
            for i, m in enumerate(maps)), rel=1e-6)
    # pos_weight 1 is the plain mean.
    assert float(grasp_loss(maps, targets, "weighted", 1.0)) == pytest.approx(float(paper),
                                                                             rel=1e-6)
    w = torch.ones(2, 8, 8)
    w[0, 2, 3] = w[1, 5, 5] = 10.0
    expect = sum(float((w * torch.nn.functional.smooth_l1_loss(m, targets[:, i],
                                                                reduction="none")).sum()
                       / w.sum()) for i, m in enumerate(maps))
    assert float(grasp_loss(maps, targets, "weighted", 10.0)) == pytest.approx(expect, rel=1e-6)
    assert float(grasp_loss(maps, targets)) == pytest.approx(expect, rel=1e-6)  # the default
    # "No grasp anywhere" costs much more under the weighted loss than under the paper's.
    zeros = tuple(torch.zeros(2, 8, 8) for _ in range(4))
    assert float(grasp_loss(zeros, targets)) > 5 * float(grasp_loss(zeros, targets, "paper"))
    with pytest.raises(ValueError, match="unknown loss"):
        grasp_loss(maps, targets, "focal")


def test_neg_weight_weighs_the_quality_term_at_labelled_failures():
    torch.manual_seed(1)
    targets = torch.zeros(2, 5, 8, 8)
    targets[0, :4, 2, 3] = torch.tensor([1.0, 0.5, -0.5, 0.2])
    targets[1, 4, 5, 5] = 1.0  # a failed grasp: quality 0 there, a known outcome
    maps = tuple(torch.randn(2, 8, 8) for _ in range(4))
    four = grasp_loss(maps, targets[:, :4], "weighted", 10.0)
    # neg_weight 1 (the default) is the loss without a mask; "paper" ignores the mask.
    assert float(grasp_loss(maps, targets, "weighted", 10.0)) == pytest.approx(float(four))
    assert float(grasp_loss(maps, targets, "paper")) == pytest.approx(
        float(grasp_loss(maps, targets[:, :4], "paper")))
    w = torch.ones(2, 8, 8)
    w[0, 2, 3] = 10.0
    w_q = w.clone()
    w_q[1, 5, 5] = 4.0
    sl1 = [torch.nn.functional.smooth_l1_loss(m, targets[:, i], reduction="none")
           for i, m in enumerate(maps)]
    expect = float((w_q * sl1[0]).sum() / w_q.sum()) + sum(
        float((w * sl1[i]).sum() / w.sum()) for i in (1, 2, 3))
    assert float(grasp_loss(maps, targets, "weighted", 10.0, 4.0)) == pytest.approx(expect,
                                                                                   rel=1e-6)
    # A high quality where the grasp failed costs more with the weight than without.
    hot = (torch.zeros(2, 8, 8).index_put_((torch.tensor([1]), torch.tensor([5]),
                                            torch.tensor([5])), torch.tensor(1.0)),
           *(torch.zeros(2, 8, 8) for _ in range(3)))
    zeros = tuple(torch.zeros(2, 8, 8) for _ in range(4))

    def cost(nw: float) -> float:
        return float(grasp_loss(hot, targets, neg_weight=nw) - grasp_loss(zeros, targets,
                                                                          neg_weight=nw))
    assert cost(10.0) > 5 * cost(1.0) > 0
    with pytest.raises(ValueError, match="neg_weight"):
        grasp_loss(maps, targets, neg_weight=0.0)


def test_width_weight_scales_the_width_term_only():
    torch.manual_seed(2)
    targets = torch.zeros(2, 5, 8, 8)
    targets[0, :4, 2, 3] = torch.tensor([1.0, 0.5, -0.5, 0.2])
    maps = tuple(torch.randn(2, 8, 8) for _ in range(4))
    base = float(grasp_loss(maps, targets))
    no_width = (*maps[:3], targets[:, 3])  # a perfect width map: its term is 0
    width_term = base - float(grasp_loss(no_width, targets))
    assert width_term > 0
    assert float(grasp_loss(maps, targets, width_weight=4.0)) == pytest.approx(
        base + 3 * width_term, rel=1e-6)
    assert float(grasp_loss(no_width, targets, width_weight=4.0)) == pytest.approx(
        float(grasp_loss(no_width, targets)), rel=1e-6)
    with pytest.raises(ValueError, match="width_weight"):
        grasp_loss(maps, targets, width_weight=-1.0)


@pytest.mark.parametrize(("optimizer", "loss"), [("rmsprop", "paper"), ("adam", "weighted")])
def test_optimizers_and_losses_are_seeded(lgdm_dir, optimizer, loss):
    tiny = ModelConfig(name="tiny", input_size=48, channels=8, encoder_res_blocks=1,
                       bottleneck_res_blocks=1)
    ds = GraspDataset(find_samples(lgdm_dir)[:4], tiny.input_size, augment=True, seed=1)
    states = []
    for _ in range(2):
        torch.manual_seed(7)
        model = GraspAutoencoder(tiny)
        hist = train_model(model, ds, epochs=1, batch_size=2, seed=1, optimizer=optimizer,
                           loss=loss)
        states.append(model.state_dict())
    assert np.isfinite(hist.epoch_loss).all()
    for k in states[0]:
        assert torch.equal(states[0][k], states[1][k]), k
    with pytest.raises(ValueError, match="unknown optimizer"):
        train_model(GraspAutoencoder(tiny), ds, 1, optimizer="sgd")


def test_train_on_lgdm_crops_holds_out_an_instance_per_category(lgdm_dir, tmp_path, capsys):
    out = tmp_path / "ae.pt"
    argv = ["--data", str(lgdm_dir), "--config", "cpu", "--epochs", "1", "--out", str(out),
            "--batch-size", "4", "--seed", "0", "--threads", "1", "--quiet"]
    assert train_cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "held out (per-category): 6 images of 2 objects" in err
    assert "optimizer adam lr 0.001, loss weighted (positives x10)" in err
    model, ckpt = load_checkpoint(out)
    assert model.config.jaw_side_fraction == pytest.approx(0.02 / 0.22)
    assert bridge.jaw_side_fraction(model) == pytest.approx(0.02 / 0.22)
    t = ckpt["metrics"]["training"]
    assert (t["optimizer"], t["loss"], t["pos_weight"], t["holdout"]) == (
        "adam", "weighted", 10.0, "per-category")
    held = ckpt["metrics"]["heldout"]["objects"]
    assert sorted(o.split("_")[0] for o in held) == ["bar", "box"]
    assert set(t["train_objects"]).isdisjoint(held)
    # Same seed, same threads: the same bytes (but for the recorded output path).
    out2 = tmp_path / "ae2.pt"
    assert train_cli.main([*argv[:7], str(out2), *argv[8:]]) == 0
    a, b = torch.load(out, weights_only=True), torch.load(out2, weights_only=True)
    assert a["metrics"] == b["metrics"] and a["config"] == b["config"]
    for k in a["state_dict"]:
        assert torch.equal(a["state_dict"][k], b["state_dict"][k]), k
    # The paper's settings and the old fraction split are still selectable.
    assert train_cli.main([*argv, "--optimizer", "rmsprop", "--loss", "paper",
                           "--holdout", "fraction", "--val-fraction", "0.25"]) == 0
    assert "held out (fraction): 3 images of 1 objects" in capsys.readouterr().err
    _, ckpt = load_checkpoint(out)
    assert ckpt["metrics"]["training"]["pos_weight"] is None
    assert evaluate_cli.main(["--data", str(lgdm_dir), "--ckpt", str(out), "--threads", "1",
                              "--quiet", "--json"]) == 0
    assert '"jaw_side_fraction": 0.09090909' in capsys.readouterr().out


def test_per_category_needs_categories(fixture_dir, tmp_path, capsys):
    argv = ["--data", str(fixture_dir), "--config", "cpu", "--epochs", "1", "--out",
            str(tmp_path / "x.pt"), "--threads", "1", "--quiet", "--holdout", "per-category"]
    assert train_cli.main(argv) == 2
    assert "needs categories" in capsys.readouterr().err


def test_perfect_maps_on_lgdm_crops_score_everything_with_the_finger_jaw(lgdm_dir):
    """With jaw = finger width the label maps decode to correct grasps; the Cornell jaw
    (opening / 2) is a different rectangle and is recorded as such."""
    ds = GraspDataset(find_samples(lgdm_dir), 112, augment=False)
    targets = [torch.from_numpy(ds.item(i)[1]) for i in range(len(ds))]

    class Oracle(torch.nn.Module):
        seen = 0

        def forward(self, x):
            y = torch.stack(targets[self.seen:self.seen + len(x)])
            self.seen += len(x)
            return tuple(y[:, k] for k in range(4))

    result = evaluate_model(Oracle(), ds, batch_size=5, jaw_side_fraction=0.02 / 0.22)
    assert result["n"] == len(ds) == result["correct"]
    # Per category and per object, the counts add up to the whole.
    cats = {s.category for s in ds.samples}
    assert set(result["per_category"]) == cats and len(cats) > 1
    assert sum(v["n"] for v in result["per_category"].values()) == result["n"]
    bins = result["per_label_count"]
    assert list(bins) == ["1-6", "7-15", "16+"]
    # Each image is binned by its own number of positive rectangles.
    counts = [len(ds.item(i)[2]) for i in range(len(ds))]
    expected = {name: sum(1 for c in counts if c and c <= top and c > low)
                for (name, top), low in zip(LABEL_COUNT_BINS, (0, 6, 15), strict=True)}
    assert {k: v["n"] for k, v in bins.items()} == expected
    assert sum(v["correct"] for v in bins.values()) == result["correct"]
    assert "per labelled grasps in the image: " in format_result(result)
    assert sum(v["correct"] for v in result["per_object"].values()) == result["correct"]
    assert result["no_grasp"] == 0


def test_bridge_preprocess_resizes_crops_like_training(lgdm_dir):
    (s, *_) = find_samples(lgdm_dir)
    rgb, depth = load_images(s)
    ds = GraspDataset([s], 112, augment=False)
    x = bridge.preprocess(rgb, depth, 112)
    assert x.shape == (4, 112, 112) and x.flags.c_contiguous and x.dtype == np.float32
    np.testing.assert_array_equal(x, ds.item(0)[0])
    assert bridge.preprocess(rgb, depth).shape == (4, 224, 224)  # no size: no resize
    np.testing.assert_array_equal(bridge.preprocess(rgb, depth, 224),
                                  bridge.preprocess(rgb, depth))
    with pytest.raises(ValueError, match="square"):
        bridge.preprocess(rgb[:200], depth[:200], 112)


def test_several_directories_train_as_one_set(lgdm_dir, fixture_dir, tmp_path, capsys):
    """Object names are shared across --data directories: a name held out is held out of all
    of them; directories made for different jaws are refused."""
    second = write_synthetic_dataset(tmp_path / "second", objects=4, images_per_object=2,
                                     seed=3, layout="lgdm", categories=2)
    out = tmp_path / "mixed.pt"
    argv = ["--data", str(lgdm_dir), str(second), "--config", "cpu", "--epochs", "1",
            "--out", str(out), "--batch-size", "4", "--threads", "1", "--quiet"]
    assert train_cli.main(argv) == 0
    assert "held out (per-category): 10 images of 2 objects" in capsys.readouterr().err
    _, ckpt = load_checkpoint(out)
    t = ckpt["metrics"]["training"]
    assert t["data"] == [str(lgdm_dir), str(second)] and t["train_images"] == 10
    assert t["init"] is None
    held = set(ckpt["metrics"]["heldout"]["objects"])
    for root in (lgdm_dir, second):
        names = {s.object_id for s in find_samples(root)}
        assert held <= names and names - held
    # A Cornell directory (opening / 2 jaws) does not mix with lgdm crops (finger jaws).
    assert train_cli.main([*argv[:3], str(fixture_dir), *argv[4:]]) == 2
    assert "jaw_side_fraction" in capsys.readouterr().err
    assert train_cli.main([*argv[:3], str(lgdm_dir), *argv[4:]]) == 2
    assert "given twice" in capsys.readouterr().err


def test_repeat_shows_one_directorys_training_images_k_times(lgdm_dir, tmp_path, capsys):
    """--repeat DIR=K multiplies that directory's training images only: held-out images are
    scored once, the other directory's count is unchanged; a DIR not among --data is an error."""
    second = write_synthetic_dataset(tmp_path / "second", objects=4, images_per_object=2,
                                     seed=3, layout="lgdm", categories=2)
    argv = ["--data", str(lgdm_dir), str(second), "--config", "cpu", "--epochs", "1",
            "--batch-size", "4", "--threads", "1", "--quiet"]
    plain, rep = tmp_path / "plain.pt", tmp_path / "rep.pt"
    assert train_cli.main([*argv, "--out", str(plain)]) == 0
    assert train_cli.main([*argv, "--out", str(rep), "--repeat", f"{second}=3"]) == 0
    err = capsys.readouterr().err
    t0 = load_checkpoint(plain)[1]["metrics"]
    t1 = load_checkpoint(rep)[1]["metrics"]
    held = set(t0["heldout"]["objects"])
    second_train = sum(1 for s in find_samples(second) if s.object_id not in held)
    assert second_train > 0
    assert t1["training"]["train_images"] == t0["training"]["train_images"] + 2 * second_train
    assert t1["training"]["repeat"] == {str(second): 3} and t0["training"]["repeat"] is None
    assert t1["heldout"]["n"] == t0["heldout"]["n"]
    assert f"({t0['training']['train_images']} distinct, --repeat)" in err
    for bad in (f"{tmp_path}=2", f"{second}=0", f"{second}=two", "3"):
        with pytest.raises(SystemExit):
            train_cli.main([*argv, "--out", str(tmp_path / "x.pt"), "--repeat", bad])
        assert "--repeat" in capsys.readouterr().err
    assert not (tmp_path / "x.pt").exists()


def test_init_starts_from_a_checkpoint(lgdm_dir, tmp_path, capsys):
    start = tmp_path / "start.pt"
    base = ["--data", str(lgdm_dir), "--config", "cpu", "--epochs", "1", "--batch-size", "4",
            "--threads", "1", "--quiet"]
    assert train_cli.main([*base, "--out", str(start), "--seed", "5"]) == 0
    tuned = tmp_path / "tuned.pt"
    # A step of lr 1e-12 leaves the weights where --init put them, not at the seeded start.
    assert train_cli.main([*base, "--out", str(tuned), "--init", str(start), "--lr", "1e-12"]) == 0
    err = capsys.readouterr().err
    assert f"starting from {start}" in err
    # A fine-tune holds out what its starting checkpoint held out (not a fresh seeded choice).
    held = load_checkpoint(start)[1]["metrics"]["heldout"]["objects"]
    assert load_checkpoint(tuned)[1]["metrics"]["heldout"]["objects"] == held
    assert "held out (init)" in err
    reseeded = tmp_path / "reseeded.pt"
    assert train_cli.main([*base, "--out", str(reseeded), "--init", str(start), "--seed", "6",
                           "--holdout", "per-category"]) == 0
    assert "held out (per-category)" in capsys.readouterr().err
    assert train_cli.main([*base, "--out", str(reseeded), "--holdout", "init"]) == 2
    assert "--holdout init needs --init CKPT" in capsys.readouterr().err
    # (the parameters: batch-norm statistics move with any step)
    a, b = (dict(load_checkpoint(p)[0].named_parameters()) for p in (start, tuned))
    weights = list(a)
    assert all(torch.allclose(a[k], b[k], atol=1e-6) for k in weights)
    fresh = tmp_path / "fresh.pt"
    assert train_cli.main([*base, "--out", str(fresh), "--lr", "1e-12"]) == 0
    c = dict(load_checkpoint(fresh)[0].named_parameters())
    assert not all(torch.allclose(a[k], c[k], atol=1e-6) for k in weights)
    init = load_checkpoint(tuned)[1]["metrics"]["training"]["init"]
    assert init["file"] == "start.pt"
    assert init["sha256"] == hashlib.sha256(start.read_bytes()).hexdigest()
    # Another architecture, or no checkpoint at all, is a clear error.
    tiny = ModelConfig(name="tiny", input_size=48, channels=8, encoder_res_blocks=1,
                       bottleneck_res_blocks=1)
    save_checkpoint(tmp_path / "tiny.pt", GraspAutoencoder(tiny), {})
    assert train_cli.main([*base, "--out", str(tuned), "--init", str(tmp_path / "tiny.pt")]) == 2
    assert "is a 'tiny' network, not --config cpu" in capsys.readouterr().err
    assert train_cli.main([*base, "--out", str(tuned), "--init", str(tmp_path / "no.pt")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_input_size_fine_tunes_at_another_resolution(lgdm_dir, tmp_path, capsys):
    start = tmp_path / "start.pt"
    base = ["--data", str(lgdm_dir), "--config", "cpu", "--epochs", "1", "--batch-size", "4",
            "--threads", "1", "--quiet"]
    assert train_cli.main([*base, "--out", str(start)]) == 0
    big = tmp_path / "big.pt"
    assert train_cli.main([*base, "--out", str(big), "--init", str(start), "--input-size",
                           "224", "--lr", "1e-12"]) == 0
    assert "input 112 -> 224 px: width head scaled by 2" in capsys.readouterr().err
    (a, _), (b, meta) = load_checkpoint(start), load_checkpoint(big)
    assert (a.config.input_size, b.config.input_size) == (112, 224)
    # Openings are pixels of the input: the width head doubles, the other three heads stay.
    assert torch.allclose(b.heads.weight[3], 2 * a.heads.weight[3], atol=1e-6)
    assert torch.allclose(b.heads.bias[3], 2 * a.heads.bias[3], atol=1e-6)
    assert torch.allclose(b.heads.weight[:3], a.heads.weight[:3], atol=1e-6)
    assert meta["metrics"]["heldout"]["n"] > 0
    # A fine-tune of it keeps its size unless told otherwise.
    again = tmp_path / "again.pt"
    assert train_cli.main([*base, "--out", str(again), "--init", str(big), "--lr", "1e-12"]) == 0
    assert load_checkpoint(again)[0].config.input_size == 224
    assert "width head" not in capsys.readouterr().err
    for bad in ("30", "8", "-4"):
        with pytest.raises(SystemExit):
            train_cli.main([*base, "--out", str(tmp_path / "x.pt"), "--input-size", bad])
        assert "--input-size must be a multiple of 4" in capsys.readouterr().err
    assert not (tmp_path / "x.pt").exists()


def test_balance_images_weighs_each_images_positives_by_its_share():
    torch.manual_seed(2)
    targets = torch.zeros(3, 4, 12, 12)
    targets[0, 0, 1:3, 1:3] = 1.0     # 4 positive pixels: a pinch or two
    targets[1, 0, 2:8, 2:8] = 1.0     # 36: many grasps
    # image 2 has no positive: its weight stays 1 everywhere
    maps = tuple(torch.randn(3, 12, 12) for _ in range(4))
    positive = (targets[:, 0] > 0).float()
    # P̄ = (4 + 36) / 2 = 20: image 0 × 5, clamped to 4; image 1 × 20/36.
    scale = torch.tensor([4.0, 20.0 / 36.0, 1.0])[:, None, None]
    w = 1.0 + 9.0 * positive * scale
    expect = sum(float((w * torch.nn.functional.smooth_l1_loss(m, targets[:, i],
                                                                reduction="none")).sum()
                       / w.sum()) for i, m in enumerate(maps))
    assert float(grasp_loss(maps, targets, "weighted", 10.0, balance_images=True)) == \
        pytest.approx(expect, rel=1e-6)
    # Off (the default), the same batch is the plain weighted loss.
    assert float(grasp_loss(maps, targets, "weighted", 10.0)) != pytest.approx(expect, rel=1e-3)
    # A batch of equal images is unchanged by balancing.
    same = targets[1:2].repeat(2, 1, 1, 1)
    two = tuple(m[:2] for m in maps)
    assert float(grasp_loss(two, same, balance_images=True)) == pytest.approx(
        float(grasp_loss(two, same)), rel=1e-6)
