"""``lgdm.GDM``: the Growing Dual-Memory network with a scikit-learn-style interface.

The Rust engine (``lgdm._lgdm.Model``) does all the work with the GIL released; this module
only turns Python and numpy inputs into the arrays it expects and keeps the scikit-learn
conventions (``get_params``/``set_params``, ``fit``/``partial_fit``/``predict``/``score``,
fitted attributes ending in ``_``).
"""

from __future__ import annotations

import json
import os
import re
import threading
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from . import _lgdm
from ._errors import ConfigError, InputError, NotFittedError

__all__ = ["GDM", "PRESETS", "Prediction", "config"]

#: Names of the hyperparameter presets (``GDM(preset=...)``).
PRESETS: tuple[str, ...] = tuple(_lgdm.PRESETS)

_SECTIONS = ("episodic", "semantic", "replay")
_TOP_LEVEL = ("seed", "metric")

ArrayLike = Any
Labels = Any  # None, an integer, or an integer array
PathLike = str | os.PathLike[str]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not a config value")


def _check_finite(key: str, value: Any) -> None:
    values = value if isinstance(value, (list, tuple, np.ndarray)) else [value]
    for v in values:
        if isinstance(v, (float, np.floating)) and not np.isfinite(v):
            err = ConfigError(f"`{key}={value!r}`: must be a finite number")
            err.field = key.replace("__", ".")
            raise err


def _document(preset: str | None, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """The config document (preset plus overrides, nested) the Rust side parses."""
    doc: dict[str, Any] = {}
    if preset is not None:
        if not isinstance(preset, str):
            raise ConfigError(
                f"preset must be a string (one of {', '.join(PRESETS)}), got {preset!r}"
            )
        doc["preset"] = preset
    for key, value in overrides.items():
        _check_finite(key, value)
        section, sep, field = key.partition("__")
        if sep:
            if section not in _SECTIONS or not field or "__" in field:
                raise ConfigError(
                    f"unknown parameter `{key}`: overrides are `seed`, `metric`, or "
                    f"`<section>__<field>` with section one of {', '.join(_SECTIONS)}"
                )
            doc.setdefault(section, {})[field] = value
        elif key in _TOP_LEVEL:
            doc[key] = value
        else:
            raise ConfigError(
                f"unknown parameter `{key}`: overrides are `seed`, `metric`, or "
                f"`<section>__<field>` with section one of {', '.join(_SECTIONS)} "
                f"(e.g. `episodic__activation_threshold=0.3`)"
            )
    return doc


def _config_json(preset: str | None, overrides: Mapping[str, Any]) -> str:
    """Validated full config as JSON; a failure names the override that caused it."""
    doc = _document(preset, overrides)
    try:
        text = json.dumps(doc, default=_json_default)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"config values must be numbers, strings, booleans or lists: {e}") from e
    try:
        return _lgdm.config_json(text)
    except ConfigError as e:
        if getattr(e, "field", None) is None:
            # A parse error (unknown field, wrong type): find the override responsible.
            for key, value in overrides.items():
                try:
                    _lgdm.config_json(
                        json.dumps(_document(preset, {key: value}), default=_json_default)
                    )
                except ConfigError as single:
                    reason = re.sub(r" at line \d+ column \d+$", "", str(single))
                    err = ConfigError(f"`{key}={value!r}`: {reason}")
                    err.field = key.replace("__", ".")
                    raise err from None
        raise


def config(preset: str | None = "paper_incremental", **overrides: Any) -> dict[str, Any]:
    """The full, validated hyperparameters of ``GDM(preset, **overrides)`` as a nested dict.

    >>> config("paper_batch")["episodic"]["activation_threshold"]
    0.7
    """
    return json.loads(_config_json(preset, overrides))


def _flatten(cfg: Mapping[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in cfg.items():
        if key in _SECTIONS and isinstance(value, Mapping):
            for field, v in value.items():
                flat[f"{key}__{field}"] = v
        else:
            flat[key] = value
    return flat


def _features(X: ArrayLike) -> np.ndarray:
    """X as a C-contiguous float32 (n, d) array, or InputError."""
    if type(X) is np.ndarray and X.dtype == np.float32 and X.ndim == 2 and X.flags.c_contiguous:
        return X  # the common case, no copy and no checks to make here
    try:
        arr = np.asarray(X)
    except Exception as e:  # ragged lists, objects numpy cannot take
        raise InputError(f"X could not be read as a numeric array: {e}") from e
    if arr.dtype.kind not in "fiu":
        raise InputError(
            f"X must hold real numbers (float32, float64 or integers), got dtype {arr.dtype}"
        )
    if arr.ndim != 2:
        hint = " (one sample: X.reshape(1, -1))" if arr.ndim == 1 else ""
        raise InputError(f"X must be 2-D (n_samples, n_features), got shape {arr.shape}{hint}")
    with np.errstate(over="ignore", invalid="ignore"):  # out-of-range values → inf: Rust names them
        return np.ascontiguousarray(arr, dtype=np.float32)


def _ids(value: Labels, n: int, name: str) -> np.ndarray | None:
    """Labels or sequence ids as a C-contiguous int64 array of length n (None stays None).

    A scalar applies to every sample. Range checks (labels 0..2**32-1 or -1, ids ≥ 0) are
    done by the Rust side, which names the offending entry.
    """
    if value is None:
        return None
    if (
        type(value) is np.ndarray
        and value.dtype == np.int64
        and value.ndim == 1
        and value.flags.c_contiguous
    ):
        return value
    if isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be integers, got a bool")
    if np.ndim(value) == 0:
        if not isinstance(value, (int, np.integer)):
            raise InputError(f"{name} must be an integer or an integer array, got {value!r}")
        if not -(2**63) <= int(value) < 2**63:
            raise InputError(f"{name} = {value} is out of the int64 range")
        return np.full(n, int(value), dtype=np.int64)
    try:
        arr = np.asarray(value)
    except Exception as e:
        raise InputError(f"{name} could not be read as an integer array: {e}") from e
    if arr.ndim != 1:
        raise InputError(f"{name} must be 1-D (n_samples,), got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        if arr.size == 0 and arr.dtype.kind == "f":
            arr = arr.astype(np.int64)
        else:
            raise InputError(f"{name} must hold integers, got dtype {arr.dtype}")
    if arr.dtype == np.uint64 and arr.size and int(arr.max()) >= 2**63:
        raise InputError(f"{name} holds {int(arr.max())}, out of the int64 range")
    return np.ascontiguousarray(arr, dtype=np.int64)


class Prediction(NamedTuple):
    """What :meth:`GDM.predict` returns, one entry per sample (unpacks as a 4-tuple)."""

    #: Instance label of the episodic memory's best node (int64; -1: the node holds none).
    instance: np.ndarray
    #: Category label of the semantic memory (int64; -1: none): the model's category answer.
    category: np.ndarray
    #: Episodic activity exp(-d) of the best node, in (0, 1] (float32).
    activation: np.ndarray
    #: Category label of the episodic memory's best node (int64; -1: none).
    category_em: np.ndarray


class GDM:
    """The Growing Dual-Memory network: lifelong recognition of object instances (episodic
    memory) and categories (semantic memory) from sequences of feature vectors.

    Parameters
    ----------
    preset : str, default "paper_incremental"
        Base hyperparameters: ``"paper_incremental"`` or ``"paper_batch"`` (the paper's tables).
    **overrides
        Fields of the config that replace the preset's values. Top-level fields by name
        (``seed=1``, ``metric="euclidean"`` or ``metric={"minkowski": {"p": 3.0}}``); fields of a
        section as ``<section>__<field>`` with section ``episodic``, ``semantic`` or ``replay``
        (``episodic__activation_threshold=0.3``, ``semantic__max_nodes=500``,
        ``replay__shuffle=False``). Validated at once: a bad value raises :class:`ConfigError`
        whose ``field`` names it (``"episodic.activation_threshold"``).

    Conventions
    -----------
    - ``X`` is a 2-D array (n_samples, n_features) of real numbers; float32 is used as is,
      other dtypes are converted to float32 (any memory layout). NaN or infinite values raise
      :class:`InputError`.
    - Labels (``instance``, ``category``) are optional, per call and per sample: ``None``
      (no labels), one integer for every sample, or an integer array of length n_samples.
      Values are ids in ``0 .. 2**32 - 1``; ``-1`` means "no label" for that sample. New
      labels may appear at any time (open-ended learning).
    - Predicted labels are int64 arrays with ``-1`` where the memory holds no label.
    - ``sequence``: the temporal context restarts whenever the sequence id changes from one
      sample to the next. ``None`` means the call's samples form one sequence, a new one for
      each call. An integer gives every sample that id (passing the same id in consecutive
      ``partial_fit`` calls continues the sequence, e.g. one frame per call); an array gives
      per-sample ids (integers ≥ 0). ``predict`` always starts its context afresh.
    - Threads: the GIL is released while the Rust engine works, and one model may be shared
      between threads. Calls that change it (``partial_fit``, ``end_episode``, ``replay``) run
      one at a time, each whole, in the order they get the model; calls that read it
      (``predict``, ``evaluate``, ``score``, ``save``, ...) run in parallel with each other and
      see the model between two changes, never in the middle of one. No call is lost. (Which of
      two concurrent ``partial_fit`` calls goes first is up to the threads; force an order to
      get a reproducible model.) ``fit`` replaces the model: calls still running on the old one
      finish there.
    """

    def __init__(self, preset: str | None = "paper_incremental", **overrides: Any) -> None:
        self._config = _config_json(preset, overrides)
        self.preset = preset
        self._overrides = dict(overrides)
        self._model: _lgdm.Model | None = None
        # Serialises the creation of the model by concurrent first partial_fit calls (the
        # native model serialises everything after that).
        self._create_lock = threading.Lock()

    # -- scikit-learn parameter protocol -------------------------------------------------------

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The constructor parameters: ``preset`` and the overrides (``deep`` is ignored)."""
        return {"preset": self.preset, **self._overrides}

    def set_params(self, **params: Any) -> GDM:
        """Sets ``preset`` and/or overrides (validated at once). They take effect at the next
        :meth:`fit`, or at the first :meth:`partial_fit` of an unfitted model; a fitted model
        keeps the hyperparameters it was created with. Returns ``self``."""
        preset = params.pop("preset", self.preset)
        overrides = {**self._overrides, **params}
        self._config = _config_json(preset, overrides)
        self.preset = preset
        self._overrides = overrides
        return self

    def get_config(self) -> dict[str, Any]:
        """The full hyperparameters as a nested dict: the fitted model's if fitted, else those
        the parameters give."""
        return json.loads(self._model.config_json if self._model is not None else self._config)

    # -- learning ------------------------------------------------------------------------------

    def _engine(self) -> _lgdm.Model:
        if self._model is None:
            raise NotFittedError("this GDM has not been fitted yet: call fit or partial_fit first")
        return self._model

    def partial_fit(
        self,
        X: ArrayLike,
        instance: Labels = None,
        category: Labels = None,
        sequence: Labels = None,
    ) -> GDM:
        """One learning pass over the samples in order (lifelong learning: the model keeps what
        it learnt before). The first call creates the model with ``n_features_in_ =
        X.shape[1]``. The whole batch is checked before any learning: on error the model is
        unchanged. Returns ``self``."""
        x = _features(X)
        n = x.shape[0]
        inst = _ids(instance, n, "instance")
        cat = _ids(category, n, "category")
        seq = _ids(sequence, n, "sequence")
        model = self._model
        if model is None:
            with self._create_lock:
                model = self._model
                if model is None:
                    # The first call creates the model and trains it before publishing it, so
                    # a failed first call leaves this GDM unfitted; concurrent first calls wait.
                    model = _lgdm.Model(self._config, x.shape[1])
                    self._last_stats = model.train(x, inst, cat, seq)
                    self._model = model
                    return self
        self._last_stats = model.train(x, inst, cat, seq)
        return self

    def fit(
        self,
        X: ArrayLike,
        instance: Labels = None,
        category: Labels = None,
        sequence: Labels = None,
        epochs: int = 1,
    ) -> GDM:
        """Trains a fresh model (anything learnt before is discarded): ``epochs`` passes over
        the samples, each followed by :meth:`end_episode` (isolated-node removal), as in the
        paper's batch protocol. No replay. Returns ``self``."""
        if isinstance(epochs, bool) or not isinstance(epochs, (int, np.integer)) or epochs < 1:
            raise InputError(f"epochs must be an integer ≥ 1, got {epochs!r}")
        x = _features(X)
        n = x.shape[0]
        inst = _ids(instance, n, "instance")
        cat = _ids(category, n, "category")
        seq = _ids(sequence, n, "sequence")
        model = _lgdm.Model(self._config, x.shape[1])
        self._last_stats = model.train(x, inst, cat, seq, epochs=int(epochs), end_episodes=True)
        self._model = model
        return self

    def end_episode(self) -> GDM:
        """Ends a learning episode: removes isolated nodes from both memories (never below two
        nodes); the next sample starts a new sequence. Returns ``self``."""
        self._engine().end_episode()
        return self

    def replay(self) -> dict[str, int]:
        """Intrinsic replay: every episodic node's trajectory along its strongest temporal
        synapses is replayed to both memories, with no stored samples. Call after an episode.
        Returns ``{"chains": ..., "samples": ...}``."""
        return self._engine().replay()

    # -- inference -----------------------------------------------------------------------------

    def predict(
        self, X: ArrayLike, sequence: Labels = None, *, no_context: bool = False
    ) -> Prediction:
        """Predicts for each sample a :class:`Prediction` ``(instance, category, activation,
        category_em)``: the episodic memory's instance label, the semantic memory's category
        label (the model's answer), the episodic activity exp(-d) in (0, 1] and the episodic
        memory's own category label (int64 labels, ``-1`` where the best node holds none).
        ``no_context=True`` matches on input weights only (the paper's "without temporal
        context at test time"). The model is not changed."""
        x = _features(X)
        seq = _ids(sequence, x.shape[0], "sequence")
        return Prediction(*self._engine().predict(x, seq, no_context))

    def evaluate(
        self,
        X: ArrayLike,
        instance: Labels = None,
        category: Labels = None,
        sequence: Labels = None,
        *,
        no_context: bool = False,
    ) -> dict[str, float]:
        """Scores against the given labels: ``n``, ``instance_accuracy`` (episodic),
        ``category_accuracy_em`` and ``category_accuracy_sm`` (episodic and semantic category
        accuracy; NaN when no sample has that label; samples labelled -1 are skipped) and the
        mean quantization errors ``quantization_error_em``/``_sm``."""
        x = _features(X)
        n = x.shape[0]
        return self._engine().evaluate(
            x,
            _ids(instance, n, "instance"),
            _ids(category, n, "category"),
            _ids(sequence, n, "sequence"),
            no_context,
        )

    def score(self, X: ArrayLike, category: Labels, sequence: Labels = None) -> float:
        """Category accuracy of the semantic memory (the model's category answer) on the
        samples with a category label."""
        if category is None:
            raise InputError("score needs the category labels")
        return float(self.evaluate(X, category=category, sequence=sequence)["category_accuracy_sm"])

    # -- fitted attributes ---------------------------------------------------------------------

    @property
    def n_features_in_(self) -> int:
        """Number of features per sample the model was fitted with."""
        return self._engine().dim

    @property
    def n_nodes_episodic_(self) -> int:
        """Node count of the episodic memory."""
        return self._engine().n_episodic

    @property
    def n_nodes_semantic_(self) -> int:
        """Node count of the semantic memory."""
        return self._engine().n_semantic

    @property
    def size_bytes_(self) -> int:
        """Size of the model's checkpoint in bytes (the model size the paper reports)."""
        return self._engine().size_bytes

    # -- persistence ---------------------------------------------------------------------------

    def to_bytes(self) -> bytes:
        """The checkpoint bytes: exactly what :meth:`save` writes and ``lgdm eval`` reads."""
        return bytes(self._engine().to_bytes())

    def save(self, path: PathLike) -> None:
        """Writes the checkpoint file atomically (temporary file, then rename). The file is
        the same format the ``lgdm`` command line writes and reads."""
        self._engine().save(os.fspath(path))

    @classmethod
    def _from_model(cls, model: _lgdm.Model) -> GDM:
        flat = _flatten(json.loads(model.config_json))
        best: tuple[str, dict[str, Any]] | None = None
        for preset in PRESETS:
            base = _flatten(json.loads(_lgdm.config_json(json.dumps({"preset": preset}))))
            overrides = {k: v for k, v in flat.items() if base.get(k) != v}
            if best is None or len(overrides) < len(best[1]):
                best = (preset, overrides)
        assert best is not None
        gdm = cls(best[0], **best[1])
        gdm._model = model
        return gdm

    @classmethod
    def from_bytes(cls, data: bytes) -> GDM:
        """A model from checkpoint bytes. Its parameters (``get_params``) are the preset closest
        to the stored config plus the overrides that give it exactly."""
        return cls._from_model(_lgdm.Model.from_bytes(bytes(data)))

    @classmethod
    def load(cls, path: PathLike) -> GDM:
        """Reads a checkpoint file written by :meth:`save` or by ``lgdm train``."""
        return cls._from_model(_lgdm.Model.load(os.fspath(path)))

    def __copy__(self) -> GDM:
        return self.__deepcopy__({})

    def __deepcopy__(self, memo: dict[int, Any]) -> GDM:
        twin = type(self)(self.preset, **self._overrides)
        if self._model is not None:
            twin._model = self._model.copy()
        return twin

    def __getstate__(self) -> dict[str, Any]:
        return {
            "preset": self.preset,
            "overrides": self._overrides,
            "model": None if self._model is None else bytes(self._model.to_bytes()),
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["preset"], **state["overrides"])
        if state["model"] is not None:
            self._model = _lgdm.Model.from_bytes(state["model"])

    def __repr__(self) -> str:
        args = [repr(self.preset)] + [f"{k}={v!r}" for k, v in self._overrides.items()]
        return f"GDM({', '.join(args)})"
