"""The learners table of docs/results.md from the `learners` run directories.

    python docs/results/learners_table.py reproduce/runs/learners

Per dataset and scenario, each learner's mean ± std over trials of G-SM category accuracy on the
held-out instances (new instance), on the test collections, and G-EM instance accuracy; and GDM
minus streaming LDA on held-out instances, paired by trial (same seeds, so the same held-out
instances), with a 95 % t interval over the trials.
"""

import json
import sys
from pathlib import Path

import numpy as np

# Two-sided 95 % Student t quantiles by degrees of freedom.
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}


def load(run: Path) -> dict:
    m = json.loads((run / "metrics.json").read_text())
    trials = sorted(m["trials"], key=lambda t: t["trial"])
    return {
        "seeds": [t["seed"] for t in trials],
        "new": np.array([t["new_instance"]["category_accuracy_sm"] for t in trials]) * 100,
        "test": np.array([t["test"]["category_accuracy_sm"] for t in trials]) * 100,
        "inst": np.array([t["test"]["instance_accuracy"] for t in trials]) * 100,
        "secs": sum(t["train_seconds"] for t in trials),
    }


def ms(x: np.ndarray) -> str:
    return f"{x.mean():.1f} ± {x.std(ddof=1) if len(x) > 1 else 0:.1f}"


def main() -> None:
    root = Path(sys.argv[1])
    print("| dataset | scenario | learner | new instance (G-SM) | test (G-SM) | instance (G-EM) "
          "| GDM − learner, new instance (95 % CI) | train s |")
    print("|---|---|---|---|---|---|---|---|")
    for dataset in ("default", "ycb"):
        for scenario in ("ni", "nc", "nic"):
            runs = {}
            for learner in ("gdm", "slda", "ncm"):
                run = root / f"{dataset}-{scenario}-{learner}"
                if (run / "metrics.json").exists():
                    runs[learner] = load(run)
            for learner, r in runs.items():
                diff = ""
                g = runs.get("gdm")
                if learner != "gdm" and g is not None and g["seeds"] == r["seeds"]:
                    d = g["new"] - r["new"]
                    h = T95.get(len(d) - 1, 1.96) * d.std(ddof=1) / np.sqrt(len(d))
                    diff = f"{d.mean():+.1f} [{d.mean() - h:+.1f}, {d.mean() + h:+.1f}]"
                print(f"| {dataset} | {scenario.upper()} | {learner} | {ms(r['new'])} | "
                      f"{ms(r['test'])} | {ms(r['inst'])} | {diff} | {r['secs']:.0f} |")


if __name__ == "__main__":
    main()
