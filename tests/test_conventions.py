"""Project-wide rules of ../shared/DESIGN.md that a test can hold."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_calibration_imports_nothing_else_of_the_project():
    for path in (ROOT / "calibration").rglob("*.py"):
        assert not _imports(path) & {"bench", "drivers", "web"}, path


def test_calibration_does_no_io():
    forbidden = {"open", "print", "input"}
    for path in (ROOT / "calibration").rglob("*.py"):
        tree = ast.parse(path.read_text())
        calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        assert not calls & forbidden, (path, calls & forbidden)
        assert not _imports(path) & {"os", "pathlib", "io", "json", "csv", "sqlite3", "serial"}, path


def test_every_public_calibration_function_cites_its_source():
    """Public functions of the numerical modules carry a docstring that names a seed or the research note."""
    for name in ("geometry", "pinhole", "models/seed003", "synthetic"):
        tree = ast.parse((ROOT / "calibration" / f"{name}.py").read_text())
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
                doc = ast.get_docstring(node) or ""
                if node.name in {"wrap_deg", "sector_of", "spot_from_vectors"}:
                    assert doc, node.name  # helpers: a docstring, the citation sits with their callers
                    continue
                assert "seed 0" in doc or "research note" in doc, f"{name}.{node.name} cites no source"
