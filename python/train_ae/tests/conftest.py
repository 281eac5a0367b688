"""Shared fixtures: tiny synthetic datasets written into temporary directories: Cornell-style
(non-square frames, object = folder, no index) and lgdm-style (224-px square crops, index.json
with objects and categories); and the Wilson-interval fixture the Rust side is pinned to.

One torch thread: on a 2-core machine shared with builds, two OpenMP threads that spin-wait for
each other are several times slower than one."""

from __future__ import annotations

import json
import os
from pathlib import Path

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


REPO = Path(__file__).resolve().parents[3]
WILSON_FIXTURE = Path(__file__).resolve().parents[3] / "tests" / "fixtures" / "wilson.json"


@pytest.fixture(scope="session")
def wilson_cases() -> list[dict]:
    """``<repo>/tests/fixtures/wilson.json``: Wilson 95 % intervals computed by the Rust formula
    (``lgdm_base::stats::wilson_interval``), a list of ``{"successes", "trials", "low",
    "high"}``. Missing or malformed is a failure, not a skip."""
    if not WILSON_FIXTURE.is_file():
        pytest.fail(f"Wilson fixture {WILSON_FIXTURE} does not exist", pytrace=False)
    cases = json.loads(WILSON_FIXTURE.read_text())
    assert isinstance(cases, list) and cases, WILSON_FIXTURE
    for c in cases:
        assert set(c) == {"successes", "trials", "low", "high"}, c
    return cases


def wilson_case(cases: list[dict], successes: int, trials: int) -> tuple[float, float]:
    """The fixture's (low, high) for ``successes`` of ``trials``; a failure if it has none."""
    for c in cases:
        if (c["successes"], c["trials"]) == (successes, trials):
            return c["low"], c["high"]
    pytest.fail(f"{WILSON_FIXTURE} has no entry for {successes}/{trials}", pytrace=False)


@pytest.fixture(scope="session")
def lgdm_binary() -> Path:
    """The lgdm binary: ``LGDM_BIN``, else ``<repo>/target/release/lgdm``. Without one the test is
    skipped; a ``LGDM_BIN`` that does not exist is a failure."""
    env = os.environ.get("LGDM_BIN")
    if env:
        path = Path(env)
        if not path.is_file():
            pytest.fail(f"LGDM_BIN={env} does not exist", pytrace=False)
        return path
    path = REPO / "target" / "release" / "lgdm"
    if not path.is_file():
        pytest.skip(f"no lgdm binary: {path} does not exist and LGDM_BIN is not set "
                    f"(cargo build --release)")
    return path
