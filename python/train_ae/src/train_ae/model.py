r"""The grasp autoencoder: a GR-ConvNet-derived encoder-decoder with a recognition feature tap.

Layout (paper configuration, 224x224 RGB-D input; ``c`` = 32 base channels)::

    input 4x224x224 (depth, R, G, B)
    conv 9x9 s1  -> c  x224x224      \
    conv 4x4 s2  -> 2c x112x112       |  GR-ConvNet encoder
    conv 4x4 s2  -> 4c x 56x 56       |
    5 residual blocks (4c, 3x3)      /
    conv 4x4 s2  -> 2c x 31x 31      \   the paper's added bottleneck
    conv 4x4 s2  ->  c x 15x 15       |  (section 4.1: "31x31, 64" and "15x15, 32")
        `-> feature tap (after batch norm, before ReLU): average pool to c x 4 x 2 -> 256-d,
            L2-normalised
    3 residual blocks (c, 3x3)        |
    deconv 4x4 s2 -> 2c x 31x 31      |
    deconv 4x4 s2 -> 4c x 56x 56     /
    deconv 4x4 s2 -> 2c x112x112     \
    deconv 4x4 s2 ->  c x224x224      |  GR-ConvNet decoder
    deconv 9x9 s1 ->  c x224x224      |  (this one without batch norm and ReLU)
    dropout 0.1, four 1x1 heads: quality, cos 2θ, sin 2θ, width (each 224x224, no activation)

The layer sizes, the pre-ReLU tap pooled to 4 x 2 cells and the head dropout follow the paper's
public code. The 56 -> 31 convolution needs 4 pixels of padding per side; it pads by replication
(the public code pads zeros) so no border output sees only padding. The transposed convolutions
are given the encoder's recorded sizes (``output_size``), so the network returns maps at the
input resolution for any input whose side is a multiple of 4.

Example::

    import torch
    from train_ae.model import GraspAutoencoder, ModelConfig

    model = GraspAutoencoder(ModelConfig.preset("cpu")).eval()
    x = torch.zeros(2, 4, 112, 112)
    features, maps = model.forward_with_features(x)   # (2, 256), GraspMaps of (2, 112, 112)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import nn

FEATURE_DIM = 256
"""Length of the recognition feature vector (the dual memory's input dimension)."""

FEATURE_ROWS = 4
"""Rows of the average-pooling grid of the feature tap; columns = 256 / (4 * tap channels)."""


@dataclass(frozen=True)
class ModelConfig:
    """Architecture hyperparameters. Plain data: stored as a dict inside checkpoints."""

    name: str = "paper"
    """Preset name, for reports only (default: "paper")."""
    in_channels: int = 4
    """Input channels: depth, R, G, B (default: 4)."""
    input_size: int = 224
    """Side of the square input image in pixels (default: 224; multiple of 4)."""
    channels: int = 32
    """Base channel count c: encoder c, 2c, 4c; bottleneck 2c, c (default: 32)."""
    encoder_res_blocks: int = 5
    """Residual blocks at 4c channels after the GR-ConvNet encoder (default: 5)."""
    bottleneck_res_blocks: int = 3
    """Residual blocks at c channels after the feature tap (default: 3)."""
    head_dropout: float = 0.1
    """Dropout before the output heads, training only (default: 0.1, as the public code)."""
    jaw_side_fraction: float | None = None
    """Not architecture: the decoding convention of the training data. A decoded grasp's jaw
    is this fraction of the map side (lgdm crops: finger width / crop side, from the dataset's
    index.json); None = opening × ``grasp.JAW_FRACTION`` (the real Cornell set). Default None;
    checkpoints without the field read as None."""

    @staticmethod
    def preset(name: str) -> ModelConfig:
        """``paper`` (2.28 M parameters, 224x224) or ``cpu`` (0.34 M parameters, 112x112)."""
        if name == "paper":
            return ModelConfig()
        if name == "cpu":
            return ModelConfig(
                name="cpu", input_size=112, channels=16, encoder_res_blocks=2,
                bottleneck_res_blocks=1,
            )
        raise ValueError(f"unknown model config {name!r}: expected 'paper' or 'cpu'")

    def to_dict(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_dict(d: dict) -> ModelConfig:
        """Validate a plain dict (e.g. from a checkpoint) into a config; errors name the field."""
        if not isinstance(d, dict):
            raise ValueError(f"model config must be a dict, got {type(d).__name__}")
        known = {f.name: f for f in fields(ModelConfig)}
        unknown = sorted(set(d) - set(known))
        if unknown:
            raise ValueError(f"model config: unknown field(s) {unknown}")
        cfg = ModelConfig(**d)
        for key in ("in_channels", "input_size", "channels"):
            v = getattr(cfg, key)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"model config: {key} must be a positive int, got {v!r}")
        for key in ("encoder_res_blocks", "bottleneck_res_blocks"):
            v = getattr(cfg, key)
            if not isinstance(v, int) or v < 0:
                raise ValueError(f"model config: {key} must be a non-negative int, got {v!r}")
        if cfg.input_size % 4:
            raise ValueError(f"model config: input_size must be a multiple of 4, got "
                             f"{cfg.input_size}")
        if FEATURE_DIM % (FEATURE_ROWS * cfg.channels):
            raise ValueError(f"model config: channels ({cfg.channels}) times {FEATURE_ROWS} must "
                             f"divide {FEATURE_DIM} for the feature pool")
        if not isinstance(cfg.head_dropout, (int, float)) or not 0 <= cfg.head_dropout < 1:
            raise ValueError(f"model config: head_dropout must be in [0, 1), got "
                             f"{cfg.head_dropout!r}")
        j = cfg.jaw_side_fraction
        if j is not None and (isinstance(j, bool) or not isinstance(j, (int, float))
                              or not 0 < j < 1):
            raise ValueError(f"model config: jaw_side_fraction must be None or in (0, 1), got "
                             f"{j!r}")
        return cfg

    @property
    def feature_grid(self) -> tuple[int, int]:
        """(rows, columns) the tap is average-pooled to: paper 4 x 2, cpu 4 x 4."""
        return FEATURE_ROWS, FEATURE_DIM // (FEATURE_ROWS * self.channels)


class GraspMaps(NamedTuple):
    """Pixel-wise grasp maps, each (N, H, W) at the input resolution."""

    quality: torch.Tensor
    cos2t: torch.Tensor
    sin2t: torch.Tensor
    width: torch.Tensor
    """Opening width divided by ``grasp.WIDTH_SCALE_PX``."""


def _conv_bn_relu(cin: int, cout: int, k: int, s: int, p: int, mode: str = "zeros") -> nn.Module:
    return nn.Sequential(
        nn.Conv2d(cin, cout, k, stride=s, padding=p, padding_mode=mode),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class ResidualBlock(nn.Module):
    """GR-ConvNet residual block: conv3x3-BN-ReLU-conv3x3-BN, plus the input."""

    def __init__(self, ch: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(ch, ch, 3, padding=1)
        self.bn1 = nn.BatchNorm2d(ch)
        self.conv2 = nn.Conv2d(ch, ch, 3, padding=1)
        self.bn2 = nn.BatchNorm2d(ch)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = F.relu(self.bn1(self.conv1(x)))
        return self.bn2(self.conv2(y)) + x


class _Deconv(nn.Module):
    """Transposed conv + BN + ReLU that lands exactly on a requested output size."""

    def __init__(self, cin: int, cout: int, k: int, s: int, p: int) -> None:
        super().__init__()
        self.conv = nn.ConvTranspose2d(cin, cout, k, stride=s, padding=p)
        self.bn = nn.BatchNorm2d(cout)

    def forward(self, x: torch.Tensor, size: tuple[int, int] | None = None) -> torch.Tensor:
        return F.relu(self.bn(self.conv(x, output_size=size)))


class GraspAutoencoder(nn.Module):
    """Encoder-decoder giving grasp maps and a 256-d L2-normalised recognition feature."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        c = config.channels
        # GR-ConvNet encoder.
        self.enc1 = _conv_bn_relu(config.in_channels, c, 9, 1, 4)
        self.enc2 = _conv_bn_relu(c, 2 * c, 4, 2, 1)
        self.enc3 = _conv_bn_relu(2 * c, 4 * c, 4, 2, 1)
        self.enc_res = nn.Sequential(
            *[ResidualBlock(4 * c) for _ in range(config.encoder_res_blocks)])
        # The paper's bottleneck; its second conv is the feature tap.
        self.down1 = _conv_bn_relu(4 * c, 2 * c, 4, 2, 4, mode="replicate")
        self.down2 = nn.Sequential(nn.Conv2d(2 * c, c, 4, stride=2, padding=1), nn.BatchNorm2d(c))
        self.mid_res = nn.Sequential(
            *[ResidualBlock(c) for _ in range(config.bottleneck_res_blocks)])
        self.up1 = _Deconv(c, 2 * c, 4, 2, 1)
        self.up2 = _Deconv(2 * c, 4 * c, 4, 2, 4)
        # GR-ConvNet decoder.
        self.dec1 = _Deconv(4 * c, 2 * c, 4, 2, 1)
        self.dec2 = _Deconv(2 * c, c, 4, 2, 1)
        self.dec3 = nn.ConvTranspose2d(c, c, 9, stride=1, padding=4)  # no BN/ReLU (GR-ConvNet)
        self.head_dropout = nn.Dropout(config.head_dropout)
        self.heads = nn.Conv2d(c, 4, 1)

    def _check_input(self, x: torch.Tensor) -> None:
        if x.ndim != 4 or x.shape[1] != self.config.in_channels:
            raise ValueError(f"expected input (N, {self.config.in_channels}, H, W), got "
                             f"{tuple(x.shape)}")
        if x.shape[2] % 4 or x.shape[3] % 4:
            raise ValueError(f"input height and width must be multiples of 4, got "
                             f"{tuple(x.shape[2:])}")

    def _encode(self, x: torch.Tensor) -> tuple[torch.Tensor, list[tuple[int, int]]]:
        self._check_input(x)
        sizes = [tuple(x.shape[2:])]
        h = self.enc1(x)
        h = self.enc2(h)
        sizes.append(tuple(h.shape[2:]))
        h = self.enc_res(self.enc3(h))
        sizes.append(tuple(h.shape[2:]))
        h = self.down1(h)
        sizes.append(tuple(h.shape[2:]))
        tap = self.down2(h)  # batch-normalised, before its ReLU
        return tap, sizes

    def _pool_features(self, tap: torch.Tensor) -> torch.Tensor:
        pooled = F.adaptive_avg_pool2d(tap, self.config.feature_grid)
        return F.normalize(pooled.flatten(1), p=2.0, dim=1, eps=1e-12)

    def _decode(self, tap: torch.Tensor, sizes: list[tuple[int, int]]) -> GraspMaps:
        h = self.mid_res(F.relu(tap))
        h = self.up1(h, sizes[3])
        h = self.up2(h, sizes[2])
        h = self.dec1(h, sizes[1])
        h = self.dec2(h, sizes[0])
        h = self.dec3(h)
        out = self.heads(self.head_dropout(h))
        return GraspMaps(out[:, 0], out[:, 1], out[:, 2], out[:, 3])

    def forward(self, x: torch.Tensor) -> GraspMaps:
        """Grasp maps (quality, cos 2θ, sin 2θ, width), each (N, H, W)."""
        tap, sizes = self._encode(x)
        return self._decode(tap, sizes)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """The (N, 256) L2-normalised recognition feature; runs the encoder only."""
        tap, _ = self._encode(x)
        return self._pool_features(tap)

    def forward_with_features(self, x: torch.Tensor) -> tuple[torch.Tensor, GraspMaps]:
        """Both outputs from one encoder pass: ((N, 256) features, grasp maps)."""
        tap, sizes = self._encode(x)
        return self._pool_features(tap), self._decode(tap, sizes)


def parameter_count(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def rescale_widths(model: GraspAutoencoder, factor: float) -> None:
    """Scale the width head (a 1x1 convolution without activation) by ``factor``, in place.

    The width map holds openings in pixels of the input (``grasp.WIDTH_SCALE_PX``), so weights
    trained at one input size and used at ``factor`` times it (e.g. 112 -> 224: 2) start with
    openings that still span the same part of the crop; the other three maps need no change."""
    with torch.no_grad():
        model.heads.weight[3].mul_(factor)
        model.heads.bias[3].mul_(factor)
