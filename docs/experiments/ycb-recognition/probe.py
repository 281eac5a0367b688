"""How far do a dataset's GOOD features carry to new instances? A validation-only probe.

For each split seed, one instance per category is drawn as the test instance and never read,
a second as the validation instance; nearest-class-mean, shrinkage LDA and 1-nearest-neighbour
(Manhattan, every fourth training view) are fitted on the other instances' training collections
but the last two, and scored per view and per sequence
(majority vote) on the validation instance, and on the trained instances' last two training
collections. Feature variants: raw, square root, L2-normalised, and GOOD with the view's three
PCA extents appended (metres × w).

    lgdm features --encoder good [--bins B] --dataset DIR --out good.npz
    python docs/experiments/ycb-recognition/probe.py good.npz DIR [--sizes]
"""

import argparse
import json

import numpy as np


def extents(dataset: str, table: dict) -> np.ndarray:
    """Each view's sorted PCA extents in metres, in the feature table's row order."""
    import lgdm

    ds = lgdm.Dataset(dataset)
    by_key = {}
    for c in range(len(ds.collections)):
        for views, info in ds.sequences(c):
            for f, v in enumerate(views):
                p = v - v.mean(0)
                q = p @ np.linalg.eigh(p.T @ p)[1]
                by_key[(c, int(info["sequence"]), f)] = np.sort(q.max(0) - q.min(0))[::-1]
    keys = zip(table["collection"], table["sequence"], table["frame"])
    return np.array([by_key[(int(c), int(s), int(f))] for c, s, f in keys])


def variants(x: np.ndarray, sizes: np.ndarray | None):
    yield "raw", x
    yield "sqrt", np.sqrt(np.maximum(x, 0))
    yield "l2", x / (np.linalg.norm(x, axis=1, keepdims=True) + 1e-12)
    if sizes is not None:
        for w in (0.3, 1, 3):
            yield f"raw+size×{w}", np.hstack([x, w * sizes])


def means(x, y):
    cs = np.unique(y)
    return cs, np.stack([x[y == c].mean(0) for c in cs])


def ncm(x, y, q):
    cs, mu = means(x, y)
    d = (q**2).sum(1)[:, None] - 2 * q @ mu.T + (mu**2).sum(1)[None]
    return cs[np.argmin(d, 1)]


def lda(x, y, q, eps=1e-4):
    cs, mu = means(x, y)
    z = x - mu[np.searchsorted(cs, y)]
    s = (1 - eps) * (z.T @ z / len(z)) + eps * np.eye(x.shape[1])
    w = np.linalg.solve(s, mu.T)
    return cs[np.argmax(q @ w - 0.5 * (mu * w.T).sum(1), 1)]


def nn1(x, y, q, chunk=32):
    """Nearest training view by Manhattan distance (the GDM's metric)."""
    out = np.empty(len(q), dtype=y.dtype)
    for i in range(0, len(q), chunk):
        d = np.abs(q[i : i + chunk, None, :] - x[None, ::4, :]).sum(2)
        out[i : i + chunk] = y[::4][np.argmin(d, 1)]
    return out


def vote(pred, seq):
    out = np.empty_like(pred)
    for u in np.unique(seq):
        m = seq == u
        vals, counts = np.unique(pred[m], return_counts=True)
        out[m] = vals[np.argmax(counts)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("table")
    ap.add_argument("dataset")
    ap.add_argument("--sizes", action="store_true", help="also GOOD + PCA extents")
    ap.add_argument("--splits", type=int, default=3)
    a = ap.parse_args()
    t = dict(np.load(a.table))
    x = t["features"].astype(np.float64)
    cat, inst, col, seq = t["category"], t["instance"], t["collection"], t["sequence"]
    with open(f"{a.dataset}/manifest.json") as f:
        manifest = json.load(f)
    train_cols = [i for i, c in enumerate(manifest["collections"]) if c["split"] == "train"]
    fit_cols, val_cols = train_cols[:-2], train_cols[-2:]
    sizes = extents(a.dataset, t) if a.sizes else None
    rows = {}
    for split in range(a.splits):
        rng = np.random.default_rng(split)
        test_i, val_i = [], []
        for c in np.unique(cat):
            ins = np.unique(inst[cat == c])
            test_i.append(rng.choice(ins))
            val_i.append(rng.choice(ins[ins != test_i[-1]]))
        keep = ~np.isin(inst, test_i)
        fit = keep & ~np.isin(inst, val_i) & np.isin(col, fit_cols)
        new = np.isin(inst, val_i) & np.isin(col, train_cols)
        old = keep & ~np.isin(inst, val_i) & np.isin(col, val_cols)
        for name, z in variants(x, sizes):
            for learner, fn in (("ncm", ncm), ("lda", lda), ("1nn", nn1)):
                p, q = fn(z[fit], cat[fit], z[new]), fn(z[fit], cat[fit], z[old])
                rows.setdefault((name, learner), []).append(
                    ((p == cat[new]).mean(), (vote(p, seq[new]) == cat[new]).mean(),
                     (q == cat[old]).mean()))
    print("| features | learner | new instance, per view | per sequence (vote) | trained instances |")
    print("|---|---|---|---|---|")
    for (name, learner), v in rows.items():
        m = np.mean(v, 0)
        print(f"| {name} | {learner} | {m[0]:.3f} | {m[1]:.3f} | {m[2]:.3f} |")


if __name__ == "__main__":
    main()
