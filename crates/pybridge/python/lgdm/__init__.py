"""lgdm: lifelong 3D object recognition with the Growing Dual-Memory network, from Rust.

- :class:`GDM`: the dual-memory model (episodic + semantic Gamma-GWR memories with temporal
  context and intrinsic replay), scikit-learn style, numpy in and out.
- :func:`config`: the full hyperparameters of a preset plus overrides.
- :func:`run_scenario`: the paper's scenarios (batch, incremental, NI, NC, NIC) over trials on a
  feature table — the same code and records as ``lgdm train``'s ``metrics.json``.
- Data: :class:`Dataset` (sequences of point clouds as numpy arrays, with labels),
  :func:`good_descriptor`, :func:`good_features`, :func:`generate_dataset`,
  :func:`project_to_image` (224×224 depth / RGB-D), :func:`view_entropy`, :func:`best_view`.
- :mod:`lgdm.sim`: the simulated robot (``lgdm sim grasp``, ``pick-place``, ``packing``) as
  calls, with grasp sources written in Python.
- Errors: :class:`LgdmError` and its subclasses.

Example::

    import numpy as np
    import lgdm

    rng = np.random.default_rng(0)
    X = np.concatenate([rng.normal(c, 0.05, (40, 3)) for c in (0.0, 1.0)])
    y = np.repeat([0, 1], 40)
    model = lgdm.GDM("paper_batch", seed=0).fit(X, instance=y, category=y, epochs=3)
    instance, category, activation, category_em = model.predict(X)
"""

from . import sim
from ._data import (
    Dataset,
    best_view,
    generate_dataset,
    good_descriptor,
    good_features,
    project_to_image,
    view_entropy,
)
from ._errors import (
    CheckpointError,
    ConfigError,
    DatasetError,
    InputError,
    InternalError,
    LgdmError,
    NotFittedError,
)
from ._experiment import (
    LEARNERS,
    SCENARIOS,
    merge_runs,
    resume_scenario,
    run_scenario,
    scenario_defaults,
)
from ._gdm import GDM, PRESETS, Prediction, config
from ._lgdm import __version__

__all__ = [
    "GDM",
    "LEARNERS",
    "PRESETS",
    "SCENARIOS",
    "CheckpointError",
    "ConfigError",
    "Dataset",
    "DatasetError",
    "InputError",
    "InternalError",
    "LgdmError",
    "NotFittedError",
    "Prediction",
    "__version__",
    "best_view",
    "config",
    "generate_dataset",
    "good_descriptor",
    "good_features",
    "merge_runs",
    "project_to_image",
    "resume_scenario",
    "run_scenario",
    "scenario_defaults",
    "sim",
    "view_entropy",
]
