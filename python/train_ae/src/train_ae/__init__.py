"""lgdm grasp autoencoder: a GR-ConvNet-derived encoder-decoder that gives a 256-d object feature
for the dual memory and pixel-wise antipodal grasp maps (quality, cos 2θ, sin 2θ, width).

Modules: ``model`` (network, configurations), ``grasp`` (rectangles, label maps, decoding, the
rectangle metric), ``data`` (Cornell-layout loading, splits, augmentation), ``training``,
``checkpoint``, ``bridge`` (what Rust calls), CLIs ``train`` and ``evaluate``, and
``synthetic`` (a tiny fixture dataset).
"""

__version__ = "0.1.0"
