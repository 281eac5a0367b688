"""Shared fixtures: tiny synthetic datasets written into temporary directories: Cornell-style
(non-square frames, object = folder, no index) and lgdm-style (224-px square crops, index.json
with objects and categories).

One torch thread: on a 2-core machine shared with builds, two OpenMP threads that spin-wait for
each other are several times slower than one."""

from __future__ import annotations

import pytest
import torch

from train_ae.synthetic import write_synthetic_dataset

torch.set_num_threads(1)


@pytest.fixture(scope="session")
def fixture_dir(tmp_path_factory):
    """4 objects (folders 01-04) x 3 images of 160x128 pixels."""
    return write_synthetic_dataset(tmp_path_factory.mktemp("grasp"), objects=4,
                                   images_per_object=3, width=160, height=128, seed=0,
                                   layout="cornell")


@pytest.fixture(scope="session")
def lgdm_dir(tmp_path_factory):
    """4 objects of 2 categories x 3 images, 224x224 crops, lgdm.grasp.v2 index."""
    return write_synthetic_dataset(tmp_path_factory.mktemp("lgdm"), objects=4,
                                   images_per_object=3, seed=0, layout="lgdm", categories=2)
