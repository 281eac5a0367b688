"""The test command's pytest plugin (``tests/pytest_no_skips.py``): a skipped test, or a file
skipped while collected, fails the run; passing and xfailing tests do not."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(
    "body, code",
    [
        ("def test_a():\n    pass\n", 0),
        ("import pytest\n\n@pytest.mark.xfail\ndef test_a():\n    assert False\n", 0),
        ("import pytest\n\ndef test_a():\n    pytest.skip('no lgdm binary')\n", 1),
        ("import pytest\npytest.importorskip('no_such_mod')\n\ndef test_a():\n    pass\n", 1),
    ],
)
def test_a_skip_fails_the_run(body: str, code: int, tmp_path: Path):
    (tmp_path / "test_case.py").write_text(body)
    env = {**os.environ, "PYTHONPATH": str(REPO / "tests")}
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "pytest_no_skips", "-p", "no:cacheprovider",
         str(tmp_path)],
        capture_output=True, text=True, env=env, cwd=tmp_path, check=False,
    )  # fmt: skip
    assert done.returncode == code, done.stdout + done.stderr
    if code:
        assert "skipped; the test command runs every test" in done.stdout
