"""Every public name is documented, and the type stubs describe the native module as built."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import lgdm
from lgdm import _lgdm

STUB = Path(lgdm.__file__).with_name("_lgdm.pyi")


def test_public_names_have_docstrings():
    for name in lgdm.__all__:
        obj = getattr(lgdm, name)
        if name in ("__version__", "PRESETS"):
            continue
        assert inspect.getdoc(obj), f"lgdm.{name} has no docstring"
    for cls in (lgdm.GDM, lgdm.Dataset):
        for attr, value in vars(cls).items():
            if attr.startswith("_"):
                continue
            assert inspect.getdoc(value), f"{cls.__name__}.{attr} has no docstring"


def stub_names() -> dict[str, set[str]]:
    """Top-level names of the stub, and for each class its members."""
    tree = ast.parse(STUB.read_text())
    names: dict[str, set[str]] = {"": set()}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names[""].add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names[""].add(node.target.id)
        if isinstance(node, ast.ClassDef):
            names[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef) and n.name != "__init__"
            }
    return names


def test_stubs_match_the_native_module():
    stubs = stub_names()
    runtime = {n for n in dir(_lgdm) if not n.startswith("__") or n == "__version__"}
    typed_only = {"SequenceInfo"}  # a TypedDict describing a plain dict
    assert stubs[""] - typed_only == runtime - {"__doc__"}, "stub and module differ"
    for cls, members in stubs.items():
        if not cls or cls in typed_only:
            continue
        actual = getattr(_lgdm, cls)
        for member in members:
            assert hasattr(actual, member), f"stub names {cls}.{member}, the module has none"
        public = {m for m in dir(actual) if not m.startswith("__")}
        assert public <= members, f"{cls} members missing from the stub: {public - members}"


def test_stub_signatures_match_the_native_functions():
    """Every native function's parameters — names, order, keyword-only or not — are the
    stub's."""
    tree = ast.parse(STUB.read_text())
    for node in tree.body:
        if not isinstance(node, ast.FunctionDef):
            continue
        a = node.args
        stub = [(p.arg, "positional") for p in a.posonlyargs + a.args]
        stub += [(p.arg, "keyword") for p in a.kwonlyargs]
        native = inspect.signature(getattr(_lgdm, node.name))
        actual = [
            (p.name, "keyword" if p.kind is p.KEYWORD_ONLY else "positional")
            for p in native.parameters.values()
        ]
        assert stub == actual, f"{node.name}: stub {stub}, module {actual}"


def test_the_python_modules_are_typed_and_export_what_they_name():
    """lgdm.sim and lgdm.sweep are typed Python (their own stubs): every name in __all__
    exists, and every public function annotates each parameter and its return."""
    import lgdm.sim
    import lgdm.sweep

    for module in (lgdm.sim, lgdm.sweep):
        for name in module.__all__:
            obj = getattr(module, name)
            if not inspect.isfunction(obj):
                continue
            signature = inspect.signature(obj)
            missing = [p for p, v in signature.parameters.items() if v.annotation is v.empty]
            assert not missing, f"{module.__name__}.{name}: {missing} not annotated"
            assert signature.return_annotation is not signature.empty, f"{name}: no return type"
            assert inspect.getdoc(obj), f"{module.__name__}.{name} has no docstring"


def test_the_crate_front_page_example_runs():
    """The Python example on `lgdm-pybridge`'s front page (its lib.rs docs) runs as written."""
    import re

    lib = Path(__file__).resolve().parents[1] / "src" / "lib.rs"
    docs = "\n".join(line[4:] for line in lib.read_text().splitlines() if line.startswith("//! "))
    blocks = re.findall(r"```python\n(.*?)```", docs, re.S)
    assert blocks, "the front page has a Python example"
    scope: dict = {}
    exec(compile(blocks[0], str(lib), "exec"), scope)
    assert scope["m"].n_features_in_ == 3
