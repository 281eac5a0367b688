"""Benchmark a grasp network on lgdm's robot from Python: ``train_ae``'s autoencoder as a grasp
callable (``lgdm.sim``'s ``grasp=``).

This is how you try your own network (GG-CNN, GR-ConvNet, …): a callable gets the robot's
object-centred crop and returns grasps in crop pixels. Here the network's four maps are decoded
by :func:`lgdm.sim.decode_grasps`, the Rust decoder ``lgdm sim grasp --grasp network`` uses, so
this script gives the robot the same grasps as that command (an ``ae`` build of ``lgdm``) and the
same counts for the same seed (``examples/python/test_network_grasps.py`` checks it), checked
against the depth as that command checks the network's (``proposal_check="refine-first"``, the
network source's default; a callable's own default is ``"contacts"``: its grasps as they come).

    OMP_NUM_THREADS=1 python examples/python/network_grasps.py --rounds 20 --seed 0

Needs the venv of the README's test command (``lgdm`` and ``train_ae`` with torch). Keep
``OMP_NUM_THREADS=1``: torch's sums, and so the grasps, depend on its thread count.
"""

from __future__ import annotations

import argparse
from typing import Any

import lgdm.sim
from train_ae import bridge


class NetworkGrasps:
    """``train_ae``'s network as a grasp source: crop → preprocess → infer → decode."""

    def __init__(self, checkpoint: str | None = None) -> None:
        self.model = bridge.load(checkpoint or bridge.default_checkpoint())
        self.size = bridge.input_size(self.model)
        self.jaw = bridge.jaw_side_fraction(self.model)
        self.calls = 0

    def __call__(self, crop: dict[str, Any]) -> list[dict[str, Any]]:
        self.calls += 1
        x = bridge.preprocess(crop["rgb"], crop["depth"], self.size)
        _, q, c, s, w = bridge.infer(self.model, x[None])
        return lgdm.sim.decode_grasps(
            q[0],
            c[0],
            s[0],
            w[0],
            num_grasps=crop["max_grasps"],
            jaw_side_fraction=self.jaw,
            crop_px=crop["rgb"].shape[0],
            decode=crop["decode"],
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenario", default="isolated")
    p.add_argument("--rounds", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--checkpoint", help="default: the shipped cpu.pt")
    p.add_argument("--out", help="write the run directory here")
    p.add_argument(
        "--proposal-check",
        default="refine-first",
        choices=["contacts", "antipodal", "refine", "refine-first"],
        help="how the robot checks each proposal against the depth (default: refine-first)",
    )
    args = p.parse_args()
    network = NetworkGrasps(args.checkpoint)
    result = lgdm.sim.grasp(
        scenario=args.scenario,
        grasp=network,
        rounds=args.rounds,
        seed=args.seed,
        proposal_check=args.proposal_check,
        out=args.out,
    )
    s = result["summary"]
    for name in ("grasp_success_rate", "placement_success_rate"):
        r = s[name]
        print(f"{name}: {r['successes']}/{r['trials']}")
    print(f"network calls: {network.calls}")


if __name__ == "__main__":
    main()
