"""The Python example in the README's "## Python" section runs as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[3] / "README.md"


def python_example() -> str:
    text = README.read_text()
    start = text.find("\n## Python")
    assert start >= 0, "README.md has no '## Python' section"
    section = text[start + 1 :]
    end = section.find("\n## ", 1)
    section = section if end < 0 else section[:end]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    assert blocks, "the '## Python' section has no ```python block"
    return blocks[0]


def test_readme_python_example_runs(tmp_path):
    script = tmp_path / "example.py"
    script.write_text(python_example())
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "test category accuracy" in done.stdout
    assert (tmp_path / "model.lgdm").is_file()


def test_readme_robot_example_runs(tmp_path):
    text = README.read_text()
    start = text.find("\n### The robot from Python")
    assert start >= 0, "README.md has no '### The robot from Python' section"
    blocks = re.findall(r"```python\n(.*?)```", text[start:], flags=re.DOTALL)
    script = tmp_path / "robot.py"
    script.write_text(blocks[0])
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    first = done.stdout.split("\n")[0].split()
    assert float(first[0]) > 0 and int(first[1]) >= 3
