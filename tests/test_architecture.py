"""Layout rules: small package roots, and imports that flow one way. ingest is the base (imports
none of sim, metrics, pipeline), metrics builds on ingest only, sim never reaches up into pipeline:
pipeline alone ties the library packages together, and their tests run without it. Imports are read
by AST, those inside functions included."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MAX_ROOT_MODULES = {"sim": 3, "pipeline": 6}  # .py files directly in the folder, __init__ included
FORBIDDEN = {  # package -> project packages its modules must not import
    "ingest": {"sim", "metrics", "pipeline"},
    "metrics": {"sim", "pipeline"},
    "sim": {"pipeline"},
}
TEST_FOLDERS = {"ingest": "tests/ingest", "sim": "tests/sim", "metrics": "tests/metrics"}  # may not exist yet


def imported_packages(path: Path, root: Path = REPO) -> dict[str, list[str]]:
    """Top-level package -> `file:line: statement` of each import in `path` (relative to `root`), at
    any nesting level; relative imports count as the file's own top-level package."""
    rel = path.relative_to(root)
    found: dict[str, list[str]] = {}
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [rel.parts[0] if node.level else node.module or ""]
        else:
            continue
        where = f"{rel.as_posix()}:{node.lineno}: {ast.unparse(node)}"
        for name in names:
            found.setdefault(name.split(".")[0], []).append(where)
    return found


def python_files(folder: str) -> list[Path]:
    root = REPO / folder
    return sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts) if root.is_dir() else []


@pytest.mark.parametrize("package", sorted(MAX_ROOT_MODULES))
def test_package_root_is_small(package):
    modules, limit = sorted(p.name for p in (REPO / package).glob("*.py")), MAX_ROOT_MODULES[package]
    assert len(modules) <= limit, f"{package}/ root holds {len(modules)} modules, at most {limit}: {modules}"


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_flow_one_way(package):
    files = python_files(package)
    assert files, f"no modules under {package}/"
    bad = [line for f in files for top, lines in imported_packages(f).items() if top in FORBIDDEN[package]
           for line in lines]
    assert not bad, f"{package}/ must not import {sorted(FORBIDDEN[package])}:\n" + "\n".join(bad)


@pytest.mark.parametrize("package", sorted(TEST_FOLDERS))
def test_library_tests_do_not_import_pipeline(package):
    """Tests of a library package test it without the pipeline (vacuous while the folder is absent)."""
    files = python_files(TEST_FOLDERS[package])
    bad = [line for f in files for line in imported_packages(f).get("pipeline", [])]
    assert not bad, f"{TEST_FOLDERS[package]}/ must not import pipeline:\n" + "\n".join(bad)


def test_import_reader_sees_function_level_imports(tmp_path):
    src = tmp_path / "sim" / "probe.py"
    src.parent.mkdir()
    src.write_text("import os\n\nfrom . import errors\n\n\ndef f():\n"
                   "    from pipeline.params import load_params\n\n    return load_params\n")
    found = imported_packages(src, tmp_path)
    assert set(found) == {"os", "sim", "pipeline"}
    assert found["pipeline"] == ["sim/probe.py:7: from pipeline.params import load_params"]


@pytest.mark.parametrize("package", ("ingest", "metrics", "pipeline", "sim"))
def test_test_folders_do_not_shadow_packages(package):
    """With no tests/__init__.py, pytest puts tests/ on sys.path, so a tests/<package>/__init__.py
    would make `import <package>` load that test folder: keep test file basenames unique instead."""
    if (REPO / "tests" / "__init__.py").exists():
        pytest.skip("tests/ is a package: tests/<package> is imported as tests.<package>")
    assert not (REPO / "tests" / package / "__init__.py").exists(), (
        f"tests/{package}/__init__.py shadows the {package} package")
