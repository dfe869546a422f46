"""Layout rules: small package roots, and imports that flow one way. ingest is the base (imports
none of sim, metrics, pipeline), metrics builds on ingest only, sim never reaches up into pipeline:
pipeline alone ties the library packages together, and their tests run without it. Within the
project no two modules import each other, directly or round a loop, and a stage (pipeline/stages/)
imports no command (pipeline/commands/): what both need lives below both (pipeline/runs/). Imports
are read by AST, those inside functions included; those under `if TYPE_CHECKING:` never run and do
not count towards a cycle."""

from __future__ import annotations

import ast
from collections.abc import Iterator
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
PACKAGES = ("ingest", "sim", "metrics", "pipeline")
STAGES, COMMANDS = "pipeline/stages", "pipeline/commands"
TYPE_CHECKING = ("TYPE_CHECKING", "typing.TYPE_CHECKING")  # `if` tests whose body never runs


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


# --- the module graph ----------------------------------------------------------------------------

def _module_file(name: str, root: Path) -> Path | None:
    """`root`-relative file of project module `name` (`a/b/__init__.py` or `a/b.py`), None if none."""
    parts = name.split(".")
    if parts[0] not in PACKAGES:
        return None
    base = Path(*parts)
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if (root / candidate).is_file():
            return candidate
    return None


def _deepest(name: str, root: Path) -> Path | None:
    """The file of the longest prefix of `name` that is a project module (`a.b.func` -> a/b.py)."""
    parts = name.split(".")
    while parts:
        if found := _module_file(".".join(parts), root):
            return found
        parts.pop()
    return None


def _run_time_imports(tree: ast.Module) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import node at any depth (functions included), except those under `if TYPE_CHECKING:`."""
    todo: list[ast.AST] = [tree]
    while todo:
        node = todo.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and ast.unparse(child.test) in TYPE_CHECKING:
                todo.extend(child.orelse)
                continue
            if isinstance(child, ast.Import | ast.ImportFrom):
                yield child
            todo.append(child)


def module_imports(path: Path, root: Path = REPO) -> dict[Path, str]:
    """Project module file -> `file:line: statement` of the first import of it in `path`. `import
    a.b` and `from a.b import f` point at a/b; `from a import b` at a/b.py when that is a module. A
    package's own `__init__.py` is not an edge of its submodules (Python runs it first, but an
    `__init__` that re-exports its modules would otherwise close a loop with each of them)."""
    rel = path.relative_to(root)
    name = ".".join(rel.with_suffix("").parts)
    package = name.removesuffix(".__init__") if rel.name == "__init__.py" else name.rpartition(".")[0]
    found: dict[Path, str] = {}
    nodes = _run_time_imports(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
    for node in sorted(nodes, key=lambda n: n.lineno):
        if isinstance(node, ast.Import):
            targets = [_deepest(a.name, root) for a in node.names]
        else:
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            subs = [_module_file(f"{base}.{a.name}", root) for a in node.names if a.name != "*"]
            targets = [f for f in subs if f] + ([_deepest(base, root)] if not all(subs) or not subs else [])
        for target in targets:
            if target is not None and target != rel:
                found.setdefault(target, f"{rel.as_posix()}:{node.lineno}: {ast.unparse(node)}")
    return found


def module_graph(root: Path = REPO) -> dict[Path, dict[Path, str]]:
    """Every project module (`root`-relative) -> the project modules it imports, with where."""
    files = [p for package in PACKAGES if (root / package).is_dir()
             for p in sorted((root / package).rglob("*.py")) if "__pycache__" not in p.parts]
    return {f.relative_to(root): module_imports(f, root) for f in files}


def import_cycles(graph: dict[Path, dict[Path, str]]) -> list[list[str]]:
    """The strongly connected components of more than one module, each as the import statements that
    join its modules (Tarjan's algorithm, iterative)."""
    index: dict[Path, int] = {}
    low: dict[Path, int] = {}
    stack: list[Path] = []
    on_stack: set[Path] = set()
    components: list[set[Path]] = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(graph[start]))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next((c for c in children if c in graph), None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(component)
    return [sorted(where for m in c for target, where in graph[m].items() if target in c) for c in components]


def test_no_import_cycles():
    cycles = import_cycles(module_graph())
    assert not cycles, ("import cycles between project modules (move what both need to the module it belongs "
                        "to, below both):\n" + "\n\n".join("\n".join(c) for c in cycles))


def test_stages_import_no_command():
    graph = module_graph()
    bad = [where for module, imports in graph.items() if module.parent.as_posix() == STAGES
           for target, where in imports.items() if Path(COMMANDS) in target.parents]
    assert not bad, (f"a stage ({STAGES}/) must not import a command ({COMMANDS}/); move what both need to "
                     f"pipeline/runs/:\n" + "\n".join(bad))


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def test_cycle_finder_sees_function_level_imports_and_ignores_type_checking(tmp_path):
    _write(tmp_path, {
        "metrics/__init__.py": "from metrics.a import f\n",
        "metrics/a.py": "def f():\n    from metrics.b import g\n\n    return g\n",
        "metrics/b.py": "from . import c\n\n\ndef g():\n    pass\n",
        "metrics/c.py": "import metrics.a\n",
        "sim/__init__.py": "",
        "sim/x.py": "from typing import TYPE_CHECKING\n\nfrom sim import y\n",
        "sim/y.py": "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from sim.x import Thing\n",
    })
    graph = module_graph(tmp_path)
    assert graph[Path("metrics/c.py")] == {Path("metrics/a.py"): "metrics/c.py:1: import metrics.a"}
    assert Path("metrics/__init__.py") not in graph[Path("metrics/a.py")]  # the package is no edge
    assert graph[Path("sim/y.py")] == {}
    assert import_cycles(graph) == [["metrics/a.py:2: from metrics.b import g",
                                     "metrics/b.py:1: from . import c",
                                     "metrics/c.py:1: import metrics.a"]]


def test_stage_importing_a_command_is_seen(tmp_path):
    _write(tmp_path, {"pipeline/stages/s.py": "def run():\n    from pipeline.commands.c import go\n",
                      "pipeline/commands/c.py": "def go():\n    pass\n"})
    assert module_graph(tmp_path)[Path("pipeline/stages/s.py")] == {
        Path("pipeline/commands/c.py"): "pipeline/stages/s.py:2: from pipeline.commands.c import go"}
