#!/usr/bin/env bash
# The project's one test command (README.md, .ci/run): sets up everything it needs from scratch
# (Rust build, Python venv, maturin build of the `lgdm` module) and runs every test.
#
# Order: lint; the venv with the Python test tools (numpy, maturin, pytest, ruff) before the Rust
# tests, which use its numpy (crates/pointcloud/tests/features_npz.rs loads a written .npz; it
# fails without numpy, it never skips); the Rust tests; the `lgdm` module and its pytest (with
# crates/pybridge/tests/test_docs.py: the docs' examples); torch and train_ae (the venv grows to
# ~5.8 GB on first use, CUDA wheels included) last, then the Rust ↔ torch bridge tests and the
# network as a Python grasp callable against the `ae` binary (examples/python).
#
# Environment:
#   LGDM_VENV      the Python venv to create or reuse (default: ~/.cache/lgdm/venv, outside the clone);
#                  exported, so the tests find the same venv
#   CARGO_TARGET_DIR  shared cargo target dir (default: ./target)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$root/target}
venv=${LGDM_VENV:-$HOME/.cache/lgdm/venv}
export LGDM_VENV="$venv"
# tests/pytest_no_skips.py (loaded with -p below): a skipped test fails the run.
export PYTHONPATH="$root/tests${PYTHONPATH:+:$PYTHONPATH}"

step() { printf '\n== %s ==\n' "$*"; }

step "rust: format, lint"
cargo fmt --all --check
cargo clippy --workspace --all-targets --release -- -D warnings

step "python: venv at $venv (the test tools; the Rust tests below use its numpy)"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -r "$root/tests/requirements-dev.txt"

step "rust: tests (release build: the contract and end-to-end tests do real work)"
cargo test --workspace --release

step "rust: the library example (one pick-and-place round from library calls; fails unless it placed an object and wrote a model)"
cargo run --release -q -p lgdm-sim --example pick_place_round > /dev/null

step "python: build and install the lgdm module (maturin)"
(
  export VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH"
  # -E ray: the sweeps' optional extra (Ray, matplotlib), so the sweep tests run.
  maturin develop --release -q -E ray -m crates/pybridge/Cargo.toml
)

step "python: lint, tests"
"$venv/bin/ruff" check crates/pybridge/python crates/pybridge/tests crates/pybridge/bench python examples tests/pytest_no_skips.py
# -rs: say why a test was skipped (test_cli.py needs the release `lgdm` binary built above).
"$venv/bin/python" -m pytest -q -rs -p pytest_no_skips crates/pybridge/tests

step "python: the grasp autoencoder (python/train_ae; pulls torch into the venv on first use: ~5.8 GB with its CUDA wheels)"
"$venv/bin/python" -m pip install -q -e python/train_ae
"$venv/bin/ruff" check python/train_ae
# test_ceiling.py generates grasp images with the release binary built above (-rs: say why a
# test was skipped).
LGDM_BIN="$CARGO_TARGET_DIR/release/lgdm" "$venv/bin/python" -m pytest -q -rs -p pytest_no_skips python/train_ae/tests

step "rust ↔ torch bridge (lgdm-pybridge feature ae, embedded Python from the venv)"
VIRTUAL_ENV="$venv" cargo test --release -p lgdm-pybridge --features ae --lib --test ae_bridge
VIRTUAL_ENV="$venv" cargo test --release -p lgdm-cli --features ae --test e2e_ae

step "a grasp network as a Python callable (examples/python): the grasps and counts of --grasp network"
# The ae build of the binary (e2e_ae above built it already; this is then a no-op). torch's sums,
# and so the grasps, depend on its thread count: one thread on both sides.
VIRTUAL_ENV="$venv" cargo build --release -q -p lgdm-cli --features ae
VIRTUAL_ENV="$venv" OMP_NUM_THREADS=1 LGDM_AE_BIN="$CARGO_TARGET_DIR/release/lgdm" \
  "$venv/bin/python" -m pytest -q -rs -p pytest_no_skips examples/python
