"""The two configurations: output shapes, parameter counts, the L2-normalised 256-d feature."""

from __future__ import annotations

import pytest
import torch

from train_ae.model import FEATURE_DIM, GraspAutoencoder, ModelConfig, parameter_count

PAPER_PARAMS = 2_284_932
"""Exact count of this implementation of the paper configuration."""
PAPER_CLAIM = 2.3e6
"""The paper's figure (section 5.2: "~2.3 M trainable parameters")."""
PAPER_TOLERANCE = 0.05
"""Accepted relative deviation from the paper's rounded figure."""
CPU_PARAMS = 343_684


def test_paper_parameter_count_matches_the_paper():
    n = parameter_count(GraspAutoencoder(ModelConfig.preset("paper")))
    assert n == PAPER_PARAMS
    assert abs(n - PAPER_CLAIM) / PAPER_CLAIM < PAPER_TOLERANCE


def test_cpu_parameter_count():
    n = parameter_count(GraspAutoencoder(ModelConfig.preset("cpu")))
    assert n == CPU_PARAMS
    assert n < PAPER_PARAMS / 5


@pytest.mark.parametrize("name", ["paper", "cpu"])
def test_output_shapes_and_unit_features(name):
    torch.manual_seed(0)
    cfg = ModelConfig.preset(name)
    model = GraspAutoencoder(cfg).eval()
    s = cfg.input_size
    x = torch.randn(2, 4, s, s)
    with torch.inference_mode():
        features, maps = model.forward_with_features(x)
        only_maps = model(x)
        only_features = model.features(x)
    assert features.shape == (2, FEATURE_DIM)
    assert torch.allclose(features.norm(dim=1), torch.ones(2), atol=1e-5)
    assert torch.equal(features, only_features)
    assert len(maps) == 4
    for m, m2 in zip(maps, only_maps, strict=True):
        assert m.shape == (2, s, s)
        assert torch.equal(m, m2)


def test_feature_tap_sizes_of_the_paper_configuration():
    model = GraspAutoencoder(ModelConfig.preset("paper")).eval()
    seen = {}
    model.down1.register_forward_hook(lambda m, i, o: seen.__setitem__("down1", o.shape))
    model.down2.register_forward_hook(lambda m, i, o: seen.__setitem__("down2", o.shape))
    with torch.inference_mode():
        model.features(torch.zeros(1, 4, 224, 224))
    assert seen["down1"] == (1, 64, 31, 31)
    assert seen["down2"] == (1, 32, 15, 15)
    assert model.config.feature_grid == (4, 2)  # 32 channels x 4 x 2 cells = 256
    assert ModelConfig.preset("cpu").feature_grid == (4, 4)  # 16 x 4 x 4 = 256


def test_features_are_pooled_before_the_relu():
    torch.manual_seed(0)
    model = GraspAutoencoder(ModelConfig.preset("cpu")).eval()
    with torch.inference_mode():
        f = model.features(torch.randn(4, 4, 112, 112))
    assert (f < 0).any() and (f > 0).any()


def test_other_input_sizes_keep_the_resolution():
    model = GraspAutoencoder(ModelConfig.preset("cpu")).eval()
    with torch.inference_mode():
        maps = model(torch.zeros(1, 4, 96, 128))
    assert maps.quality.shape == (1, 96, 128)


def test_bad_input_is_rejected():
    model = GraspAutoencoder(ModelConfig.preset("cpu")).eval()
    with pytest.raises(ValueError, match="multiples of 4"):
        model(torch.zeros(1, 4, 110, 112))
    with pytest.raises(ValueError, match="expected input"):
        model(torch.zeros(1, 3, 112, 112))


def test_config_round_trip_and_validation():
    cfg = ModelConfig.preset("cpu")
    assert ModelConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError, match="input_size"):
        ModelConfig.from_dict({**cfg.to_dict(), "input_size": 110})
    with pytest.raises(ValueError, match="unknown field"):
        ModelConfig.from_dict({**cfg.to_dict(), "dropout": 0.1})
    with pytest.raises(ValueError, match="unknown model config"):
        ModelConfig.preset("huge")
