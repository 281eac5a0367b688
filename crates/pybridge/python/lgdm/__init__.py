"""lgdm: lifelong 3D object recognition with the Growing Dual-Memory network."""

from ._lgdm import __version__

__all__ = ["__version__"]
