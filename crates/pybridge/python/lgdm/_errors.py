"""The exception hierarchy of ``lgdm``: every error the package raises derives from
:class:`LgdmError` and carries the Rust error's message.

The classes that signal bad values also derive from :class:`ValueError` (and
:class:`NotFittedError` from :class:`AttributeError`, as in scikit-learn), so generic
``except ValueError`` handlers keep working.
"""

from __future__ import annotations

__all__ = [
    "CheckpointError",
    "ConfigError",
    "DatasetError",
    "InputError",
    "InternalError",
    "LgdmError",
    "NotFittedError",
]


class LgdmError(Exception):
    """Base class of every error raised by ``lgdm``."""


class ConfigError(LgdmError, ValueError):
    """A hyperparameter is invalid, unknown, or a preset name is unknown.

    ``field`` names the offending config field in dotted form (``"episodic.beta"``) when the
    Rust validation identified one, else it is ``None``.
    """

    field: str | None = None


class InputError(LgdmError, ValueError):
    """Bad input data: wrong dtype or shape, NaN or infinite values, mismatched lengths,
    labels or sequence ids out of range, an empty batch, a feature count that differs from the
    fitted model's."""


class NotFittedError(LgdmError, ValueError, AttributeError):
    """The model has not been trained yet (it has no nodes)."""


class CheckpointError(LgdmError):
    """A model file or byte string could not be written or read (I/O error, not an lgdm
    checkpoint, unsupported version, truncated, checksum mismatch, corrupt content)."""


class DatasetError(LgdmError):
    """A dataset could not be opened or read, or a point cloud could not be processed."""


class InternalError(LgdmError, RuntimeError):
    """A bug inside lgdm (a Rust panic) interrupted a call. If the call was changing a model
    (training, episode end, replay), the model may be half-updated, so it refuses every later
    call with this error: load it again from a checkpoint. Please report the message."""
