"""The example's network callable gives the robot the grasps ``lgdm sim grasp --grasp network``
gives: the same attempts (grasps, outcomes, failure reasons) and counts for the same seed, on
the isolated and the packed table.

Needs an ``ae`` build of the ``lgdm`` binary in ``LGDM_AE_BIN`` (the README's test command
builds one) and the venv with ``lgdm`` and ``train_ae``; run with ``OMP_NUM_THREADS=1``.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import lgdm.sim
import pytest
from network_grasps import NetworkGrasps


def _attempts(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Each attempt without its wall times."""
    return [{k: v for k, v in a.items() if k != "wall"} for a in results["attempts"]]


@pytest.mark.parametrize("scenario, rounds, seed", [("isolated", 6, 5), ("packed", 1, 2)])
def test_the_callable_gives_the_grasps_of_grasp_network(
    tmp_path: Path, scenario: str, rounds: int, seed: int
):
    binary = os.environ.get("LGDM_AE_BIN")
    if not binary:
        pytest.fail("LGDM_AE_BIN names no `lgdm` binary built with --features ae")
    assert os.environ.get("OMP_NUM_THREADS") == "1", "torch's thread count changes the grasps"
    out = tmp_path / "cli"
    subprocess.run(
        [binary, "sim", "grasp", "--grasp", "network", "--scenario", scenario]
        + ["--rounds", str(rounds), "--seed", str(seed), "--progress", "none", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    cli = json.loads((out / "results.json").read_text())
    network = NetworkGrasps()
    # The network source's default check; a Python callable's is `contacts`.
    py = lgdm.sim.grasp(
        scenario=scenario,
        grasp=network,
        rounds=rounds,
        seed=seed,
        proposal_check="refine-first",
    )
    assert network.calls >= rounds and py["attempts"]
    assert _attempts(py) == _attempts(cli)
    for rate in ("grasp_success_rate", "placement_success_rate", "cleared_fraction"):
        assert py["summary"][rate] == cli["summary"][rate], rate
