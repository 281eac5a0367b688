"""Per-sample cost of ``lgdm.GDM.predict`` and ``partial_fit`` through Python versus the same
Rust call timed natively inside the extension (``Model._bench_predict`` / ``_bench_train``
time only the Rust ``Gdm::predict`` / ``Gdm::train`` call on prepared samples). The difference
is the Python layer: argument checks, array conversion, sample construction, result arrays,
releasing and re-taking the GIL.

Usage (after ``maturin develop --release -m crates/pybridge/Cargo.toml``)::

    python crates/pybridge/bench/bench_overhead.py [--dim 256] [--rounds 15] [--json out.json]

The model: ``paper_incremental`` trained (2 epochs) on 200 objects × 10 views of clustered
synthetic 256-d features (about 600 episodic nodes, the size of a real run). Each
``partial_fit`` measurement starts from a fresh copy of that model (``copy.deepcopy`` in
Python, ``clone`` in Rust; copying is not timed). Python and native measurements are
interleaved, each round taking the best of several calls for short batches (20 calls of one
sample, 5 of 100); the minimum over the rounds is the cost least disturbed by other processes
(the figure to compare on a shared machine), the median is printed beside it. Inputs are float32
C-contiguous (no conversion copy); ``--float64`` passes float64 to show the conversion's cost.
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import time
import timeit

import numpy as np

import lgdm


def objects(n_objects: int, frames: int, dim: int, seed: int) -> dict[str, np.ndarray]:
    """Views of objects: one Gaussian cluster (σ 0.0015) per object around centres N(0, 0.05²)."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(0.0, 1.0, (n_objects, dim))
    x = np.repeat(centres, frames, axis=0) + rng.normal(0.0, 0.03, (n_objects * frames, dim))
    ids = np.repeat(np.arange(n_objects), frames)
    return {"X": (0.05 * x).astype(np.float32), "instance": ids, "category": ids // 2}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dim", type=int, default=256)
    ap.add_argument("--rounds", type=int, default=15, help="interleaved measurements per cell")
    ap.add_argument("--float64", action="store_true", help="pass float64 arrays from Python")
    ap.add_argument("--json", help="also write the figures to this file")
    args = ap.parse_args()

    train = objects(200, 10, args.dim, seed=0)
    model = lgdm.GDM(seed=0).fit(train["X"], train["instance"], train["category"], epochs=2)
    engine = model._model
    probe = objects(200, 50, args.dim, seed=0)  # same objects, new noise: 10,000 views
    order = np.random.default_rng(1).permutation(len(probe["X"]))
    print(
        f"dim {args.dim}, episodic nodes {model.n_nodes_episodic_}, semantic nodes "
        f"{model.n_nodes_semantic_}, input {'float64' if args.float64 else 'float32'}; "
        f"µs per sample, min (median) over {args.rounds} rounds"
    )
    print(f"{'call':<12}{'batch':>7}{'python':>20}{'native':>20}{'overhead':>18}")
    rows = []
    for batch in (1, 100, 10_000):
        idx = np.sort(order[:batch])
        x32 = np.ascontiguousarray(probe["X"][idx])
        x_in = x32.astype(np.float64) if args.float64 else x32
        inst, cat = probe["instance"][idx], probe["category"][idx]

        def py_predict(x_in=x_in) -> float:
            t0 = time.perf_counter()
            model.predict(x_in)
            return time.perf_counter() - t0

        def native_predict(x32=x32) -> float:
            return engine._bench_predict(x32, 1)[0]

        def py_fit(x_in=x_in, inst=inst, cat=cat) -> float:
            fresh = copy.deepcopy(model)
            t0 = time.perf_counter()
            fresh.partial_fit(x_in, inst, cat)
            return time.perf_counter() - t0

        def native_fit(x32=x32, inst=inst, cat=cat) -> float:
            return engine._bench_train(x32, inst, cat, 1)[0]

        for name, py_fn, native_fn in (
            ("predict", py_predict, native_predict),
            ("partial_fit", py_fit, native_fit),
        ):
            py_fn(), native_fn()  # warm up
            rounds = args.rounds if batch < 10_000 else max(3, args.rounds // 3)
            inner = {1: 20, 100: 5}.get(batch, 1)  # short calls: best of several per round
            py_t, native_t = [], []
            for _ in range(rounds):
                py_t.append(min(py_fn() for _ in range(inner)))
                native_t.append(min(native_fn() for _ in range(inner)))
            row = {"call": name, "batch": batch}
            for stat, f in (("min", min), ("median", statistics.median)):
                py_s, native_s = f(py_t), f(native_t)
                row[f"python_us_{stat}"] = py_s / batch * 1e6
                row[f"native_us_{stat}"] = native_s / batch * 1e6
                row[f"overhead_{stat}"] = py_s / native_s - 1.0
            rows.append(row)
            print(
                f"{name:<12}{batch:>7}"
                f"{row['python_us_min']:>10.2f} ({row['python_us_median']:>7.2f})"
                f"{row['native_us_min']:>10.2f} ({row['native_us_median']:>7.2f})"
                f"{row['overhead_min']:>9.1%} ({row['overhead_median']:>6.1%})"
            )
    # The Python layer's fixed cost per call, measured where Rust has almost nothing to do (a
    # two-node model, one sample): robust to background load, unlike differences of big timings.
    tiny = lgdm.GDM(seed=0).partial_fit(np.zeros((2, args.dim), np.float32))
    x1 = np.zeros((1, args.dim), np.float32)
    one = np.zeros(1, np.int64)
    n = 20_000

    def per_call(fn) -> float:
        return min(timeit.repeat(fn, number=n, repeat=5)) / n

    fixed = {  # whole Python call minus the Rust call alone (timed inside the extension)
        "predict": per_call(lambda: tiny.predict(x1))
        - statistics.median(tiny._model._bench_predict(x1, n)),
        "partial_fit": per_call(lambda: tiny.partial_fit(x1, one, one))
        - statistics.median(tiny._model._bench_train(x1, one, one, n)),
    }
    print("Python layer's fixed cost per call (tiny model, 1 sample), and what it adds to the")
    print("native time per call above:")
    for row in rows:
        native_call = row["native_us_min"] * row["batch"]
        row["fixed_us_per_call"] = fixed[row["call"]] * 1e6
        row["fixed_overhead"] = fixed[row["call"]] * 1e6 / native_call
        print(
            f"{row['call']:<12}{row['batch']:>7}{row['fixed_us_per_call']:>10.2f} µs"
            f"{row['fixed_overhead']:>10.2%}"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"dim": args.dim, "float64": args.float64, "rows": rows}, f, indent=2)


if __name__ == "__main__":
    main()
