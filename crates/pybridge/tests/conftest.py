"""Shared fixtures: synthetic sequential data with instance and category labels."""

from __future__ import annotations

import numpy as np
import pytest


def make_objects(
    n_categories: int = 4,
    instances_per_category: int = 2,
    frames: int = 20,
    dim: int = 16,
    noise: float = 0.03,
    seed: int = 0,
    first_category: int = 0,
) -> dict[str, np.ndarray]:
    """Objects as sequences of views: each instance is a Gaussian cluster whose centre drifts
    slowly over its sequence (a turntable), instances of one category lie near each other,
    categories far apart. Returns X (float64), instance, category and sequence arrays."""
    rng = np.random.default_rng(seed)
    xs, inst, cat, seq = [], [], [], []
    for c in range(n_categories):
        category_centre = rng.normal(0.0, 1.0, dim)
        for k in range(instances_per_category):
            centre = category_centre + rng.normal(0.0, 0.25, dim)
            drift = rng.normal(0.0, 0.01, dim)
            i = (first_category + c) * instances_per_category + k
            for t in range(frames):
                xs.append(centre + t * drift + rng.normal(0.0, noise, dim))
                inst.append(i)
                cat.append(first_category + c)
                seq.append(i)
    return {
        "X": np.asarray(xs),
        "instance": np.asarray(inst, dtype=np.int64),
        "category": np.asarray(cat, dtype=np.int64),
        "sequence": np.asarray(seq, dtype=np.int64),
    }


@pytest.fixture
def objects() -> dict[str, np.ndarray]:
    """Training views of 4 categories × 2 instances, 20 frames each, 16-d."""
    return make_objects()


@pytest.fixture
def held_out() -> dict[str, np.ndarray]:
    """New views (other noise) of the same objects as ``objects``."""
    data = make_objects()
    rng = np.random.default_rng(99)
    data["X"] = data["X"] + rng.normal(0.0, 0.03, data["X"].shape)
    return data


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory):
    """The ``small`` dataset preset (10 categories × 3 instances, 15 collections), cut to 4
    frames per sequence and 1 grasp image so it generates in a few seconds."""
    import lgdm

    out = tmp_path_factory.mktemp("dataset") / "small"
    return lgdm.generate_dataset(out, "small", seed=0, frames=4, grasp_images=1)
