"""The QD package keeps the project's rules: pure numerics citing their source, no I/O, nothing outside calibration."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[3] / "calibration" / "qd"
SOURCES = ("seed 0", "research note", "digest", "DESIGN.md")


def _modules():
    return sorted(PACKAGE.glob("*.py"))


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.name)
def test_every_public_function_cites_its_source(path):
    tree = ast.parse(path.read_text())
    assert any(s in (ast.get_docstring(tree) or "") for s in SOURCES), f"{path.name}: module docstring cites nothing"
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            doc = ast.get_docstring(node) or ""
            assert any(s in doc for s in SOURCES), f"{path.name}.{node.name} cites no source"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.name)
def test_imports_only_numpy_scipy_and_calibration(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name.split(".")[0] for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module.split(".")[0]]
        else:
            continue
        assert set(names) <= {"numpy", "scipy", "calibration", "__future__", "dataclasses", "math", "re", "types",
                              "typing"}, (path.name, names)
