"""A pytest plugin for the test command (``tests/run-all.sh`` loads it with ``-p
pytest_no_skips``): a test skipped for any reason — a missing ``lgdm`` binary, Ray, numpy, torch —
fails the run, so that CI cannot pass by not testing. The skipped tests are listed with their
reasons. Expected failures (``xfail``) are not skips."""

from __future__ import annotations

import pytest

_skipped: list[tuple[str, str]] = []


def _reason(report: pytest.TestReport | pytest.CollectReport) -> str:
    return report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.skipped and not hasattr(report, "wasxfail"):
        _skipped.append((report.nodeid, _reason(report)))


def pytest_collectreport(report: pytest.CollectReport) -> None:
    # A module-level skip (pytest.importorskip) skips a whole file while collecting it.
    if report.skipped:
        _skipped.append((report.nodeid, _reason(report)))


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _skipped:
        lines = "\n".join(f"  {nodeid}: {reason}" for nodeid, reason in _skipped)
        print(f"\nerror: {len(_skipped)} test(s) skipped; the test command runs every test:\n{lines}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
