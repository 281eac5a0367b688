"""The Wilson 95 % interval of the rectangle metric is the Rust one: ``wilson_interval`` gives
the values of ``<repo>/tests/fixtures/wilson.json`` (computed with the Rust formula,
``lgdm_base::stats::wilson_interval``, which a Rust test pins to the same file) to 1e-12, and is
exact at the ends (0 successes → low 0.0, no failures → high 1.0, no trials → (0, 1))."""

from __future__ import annotations

import pytest
from conftest import wilson_case

from train_ae.grasp import wilson_interval


def test_matches_the_shared_fixture(wilson_cases):
    for c in wilson_cases:
        lo, hi = wilson_interval(c["successes"], c["trials"])
        assert lo == pytest.approx(c["low"], abs=1e-12, rel=0), c
        assert hi == pytest.approx(c["high"], abs=1e-12, rel=0), c


def test_fixture_covers_the_ends_and_known_values(wilson_cases):
    """The fixture keeps the cases that matter: no trials, 0/n, n/n, 1/1 and the values the
    Rust doc test states."""
    pairs = {(c["successes"], c["trials"]) for c in wilson_cases}
    for pair in [(0, 0), (0, 1), (1, 1), (0, 10), (10, 10), (8, 10), (705, 751), (1, 3),
                 (50, 100)]:
        assert pair in pairs, f"{pair} missing from the fixture"
    lo, hi = wilson_case(wilson_cases, 8, 10)
    assert abs(lo - 0.4902) < 1e-4 and abs(hi - 0.9433) < 1e-4
    # 50/100 is symmetric about 0.5.
    lo, hi = wilson_case(wilson_cases, 50, 100)
    assert lo + hi == pytest.approx(1.0, abs=1e-12)


def test_exact_at_the_ends(wilson_cases):
    assert wilson_interval(0, 0) == (0.0, 1.0)
    for c in wilson_cases:
        s, n = c["successes"], c["trials"]
        lo, hi = wilson_interval(s, n)
        if s == 0:
            assert lo == 0.0 == c["low"], c
        if s == n:
            assert hi == 1.0 == c["high"], c
        if 0 < s < n:
            assert 0.0 < lo < s / n < hi < 1.0, c
    # The old formula's rounding gave 0.9999999999999999 here.
    assert wilson_interval(10, 10)[1] == 1.0
