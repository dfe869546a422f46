"""dvc.yaml's code deps are exactly the project modules a stage runs: they cover every one, so `dvc
repro` never serves a result made by older code, and nothing else, so a change to code a stage does
not run does not rerun it (a change under metrics/ reruns the stages that import that module only).

A stage's code is found from its `cmd` (`python -m pipeline <command> ...`): `pipeline/__main__.py`
and, by AST, the transitive closure of the project modules (packages ingest, sim, metrics,
pipeline) it imports. Module-level and function-level imports both count (a function's import runs
when the function is called), except the imports inside *other* commands' handlers: the handler of
each command comes from the real argparse parser (`set_defaults(func=...)`), and only this
command's handler runs. `from pkg import name` counts `pkg/name.py` when it exists, and every
package's `__init__.py` along a module's path counts (Python executes it). Each of those files must
lie under one of the stage's deps (the file itself or a folder holding it), and every module under a
code dep (a dep inside ingest, sim, metrics or pipeline) must be one the stage runs (`code_deps`
gives the shortest such list: a folder whose modules all run, else its files); data deps are not
checked. Dynamic imports (`importlib.import_module` of a controller named in params) are not seen.
A package's data files (pyproject's `[tool.setuptools.package-data]`, e.g. the report templates)
are read by its code, not imported: they count for every stage that runs the package.
"""

from __future__ import annotations

import argparse
import ast
import copy
import inspect
import os
import re
import shlex
import tomllib
from collections.abc import Iterable, Mapping
from functools import cache
from pathlib import Path, PurePosixPath

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DVC_YAML = REPO / "dvc.yaml"
PYPROJECT = REPO / "pyproject.toml"
PACKAGES = ("ingest", "sim", "metrics", "pipeline")
ENTRY = Path("pipeline/__main__.py")  # `python -m pipeline`
HandlerKey = tuple[Path, str]  # (repo-relative file, top-level function name)


# --- modules -------------------------------------------------------------------------------------


def module_file(name: str) -> Path | None:
    """Repo-relative file of project module `name` (`a/b.py` or `a/b/__init__.py`), None if it is
    not a project module or does not exist."""
    parts = name.split(".")
    if parts[0] not in PACKAGES:
        return None
    base = Path(*parts)
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if (REPO / candidate).is_file():
            return candidate
    return None


def module_files(name: str) -> set[Path]:
    """The files Python executes to import `name`: each package `__init__.py` on the way, then
    the module itself."""
    parts, files = name.split("."), set()
    for i in range(1, len(parts) + 1):
        f = module_file(".".join(parts[:i]))
        if f is None:
            break
        files.add(f)
    return files


def module_name(path: Path) -> str:
    parts = path.with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def _tree(path: Path) -> ast.Module:
    return ast.parse((REPO / path).read_text(encoding="utf-8"), filename=str(path))


def _nodes(node: ast.AST, skip: frozenset[str]) -> Iterable[ast.AST]:
    """Every node under `node`, leaving out the bodies of top-level functions named in `skip`."""
    for child in ast.iter_child_nodes(node):
        if (isinstance(node, ast.Module) and isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
                and child.name in skip):
            continue
        yield child
        yield from _nodes(child, skip)


def imported_files(path: Path, skip: frozenset[str] = frozenset()) -> set[Path]:
    """Project files that the imports in `path` (any level; not inside the top-level functions
    named in `skip`) make Python execute."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    files: set[Path] = set()
    for node in _nodes(_tree(path), skip):
        if isinstance(node, ast.Import):
            for alias in node.names:
                files |= module_files(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            files |= module_files(base)
            for alias in node.names:
                if alias.name != "*" and module_file(f"{base}.{alias.name}"):
                    files |= module_files(f"{base}.{alias.name}")
    return files


# --- commands ------------------------------------------------------------------------------------


def _key(func) -> HandlerKey:
    return Path(inspect.getsourcefile(func)).resolve().relative_to(REPO), func.__name__


@cache
def handlers() -> dict[str, HandlerKey]:
    """Command name -> its handler, from the real parser."""
    from pipeline.cli import build_parser

    (sub,) = (a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {name: _key(p.get_default("func")) for name, p in sub.choices.items()}


def command_of(cmd: str) -> str:
    argv = shlex.split(cmd)
    assert argv[:3] == ["python", "-m", "pipeline"], f"not a `python -m pipeline` command: {cmd!r}"
    commands = [a for a in argv[3:] if a in handlers()]
    assert commands, f"no pipeline command in {cmd!r} (known: {', '.join(sorted(handlers()))})"
    return commands[0]


def stage_modules(cmd: str) -> set[Path]:
    """Repo-relative project files that `cmd` (`python -m pipeline <command> ...`) executes or may
    execute: the closure of imports from `pipeline/__main__.py`, with other commands' handlers
    left out."""
    mine = handlers()[command_of(cmd)]
    skip: dict[Path, set[str]] = {}
    for key in set(handlers().values()) - {mine}:
        skip.setdefault(key[0], set()).add(key[1])
    todo = module_files(module_name(ENTRY)) | {ENTRY, mine[0]}
    seen: set[Path] = set()
    while todo:
        path = todo.pop()
        seen.add(path)
        todo |= imported_files(path, frozenset(skip.get(path, ()))) - seen
    return seen


@cache
def package_data() -> dict[str, tuple[str, ...]]:
    """pyproject's `[tool.setuptools.package-data]`: package -> globs of the files beside its code."""
    setuptools = tomllib.loads(PYPROJECT.read_text())["tool"]["setuptools"]
    return {package: tuple(globs) for package, globs in setuptools.get("package-data", {}).items()}


def data_files(modules: Iterable[Path]) -> set[Path]:
    """The package data files (repo-relative) of the packages among `modules` (their
    `__init__.py` runs whenever one of their modules does)."""
    inits = {m.as_posix() for m in modules if m.name == "__init__.py"}
    files: set[Path] = set()
    for package, globs in package_data().items():
        folder = Path(*package.split("."))
        if (folder / "__init__.py").as_posix() in inits:
            files |= {f.relative_to(REPO) for g in globs for f in (REPO / folder).glob(g) if f.is_file()}
    return files


def stage_files(cmd: str) -> set[Path]:
    """What `cmd` runs (`stage_modules`) and the package data those modules read (`data_files`)."""
    modules = stage_modules(cmd)
    return modules | data_files(modules)


def uncovered(stage_deps: Iterable[str], modules: Iterable[Path | str]) -> list[str]:
    """The modules (repo-relative) that no dep covers; a dep covers itself and, if a folder,
    everything under it."""
    deps = [PurePosixPath(os.path.normpath(d).replace(os.sep, "/")) for d in stage_deps]
    out = []
    for m in modules:
        m = Path(m)
        rel = PurePosixPath((m.resolve().relative_to(REPO) if m.is_absolute() else m).as_posix())
        if not any(rel == d or d in rel.parents for d in deps):
            out.append(rel.as_posix())
    return sorted(out)


# --- dvc.yaml ------------------------------------------------------------------------------------


def _subject() -> str:
    subjects = yaml.safe_load((REPO / "params.yaml").read_text()).get("subjects") or ["subject"]
    return str(subjects[0])


def _substitute(value, subject: str):
    if isinstance(value, str):
        value = re.sub(r"\$\{\s*(item|key)\s*\}", subject, value)
        return re.sub(r"\$\{[^}]*\}", "", value)  # ${item.args} and the like: extra arguments
    if isinstance(value, list):
        return [_substitute(v, subject) for v in value]
    if isinstance(value, dict):
        return {_substitute(k, subject): _substitute(v, subject) for k, v in value.items()}
    return value


def stages(doc: Mapping) -> dict[str, dict]:
    """Stage name -> {cmd, deps} with `foreach`/`do` bodies filled in for one subject."""
    out, subject = {}, _subject()
    for name, spec in doc["stages"].items():
        body = _substitute(spec["do"] if "foreach" in spec else spec, subject)
        deps = [d if isinstance(d, str) else next(iter(d)) for d in body.get("deps", [])]
        out[name] = {"cmd": body["cmd"], "deps": deps}
    return out


def python_files(folder: PurePosixPath) -> set[PurePosixPath]:
    root = REPO / folder
    if root.is_file():
        return {folder}
    return {PurePosixPath(p.relative_to(REPO).as_posix()) for p in root.rglob("*.py")
            if "__pycache__" not in p.parts}


def is_code(dep: str) -> bool:
    return PurePosixPath(os.path.normpath(dep)).parts[0] in PACKAGES


def unneeded(stage_deps: Iterable[str], modules: Iterable[Path | str]) -> list[str]:
    """The project modules under the code deps (deps inside the packages) that the stage does not
    run: a dep broader than the code (a change there would rerun the stage for nothing)."""
    runs = {PurePosixPath(Path(m).as_posix()) for m in modules}
    out: set[str] = set()
    for dep in filter(is_code, stage_deps):
        out |= {f.as_posix() for f in python_files(PurePosixPath(os.path.normpath(dep))) - runs}
    return sorted(out)


def code_deps(modules: Iterable[Path | str]) -> list[str]:
    """The shortest list of code deps that is exactly `modules`: a folder whose every module is
    among them, else its files and the subfolders that qualify."""
    runs = {PurePosixPath(Path(m).as_posix()) for m in modules}

    def cover(folder: PurePosixPath) -> list[str]:
        files = python_files(folder)
        if files and files <= runs:
            return [folder.as_posix()]
        out = []
        for child in sorted((REPO / folder).iterdir()):
            rel = PurePosixPath(child.relative_to(REPO).as_posix())
            if child.is_dir() and python_files(rel) & runs:
                out += cover(rel)
            elif rel in runs:
                out.append(rel.as_posix())
        return out

    return [d for package in PACKAGES for d in cover(PurePosixPath(package))]


def problems(doc: Mapping) -> dict[str, list[str]]:
    """Stage name -> what its command runs (modules and the package data they read) that its deps
    miss, and the modules under its code deps that it does not run (stages with none left out)."""
    found = {}
    for name, st in stages(doc).items():
        runs = stage_files(st["cmd"])
        found[name] = [*uncovered(st["deps"], runs), *(f"unneeded {m}" for m in unneeded(st["deps"], runs))]
    return {name: issues for name, issues in found.items() if issues}


def load_dvc_yaml() -> dict:
    return yaml.safe_load(DVC_YAML.read_text())


# --- tests ---------------------------------------------------------------------------------------

STAGES = stages(load_dvc_yaml())


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_stage_deps_cover_the_code_it_runs(stage):
    spec = STAGES[stage]
    missing = uncovered(spec["deps"], stage_files(spec["cmd"]))
    assert not missing, (f"dvc.yaml stage {stage!r} (`{spec['cmd']}`) runs {missing} but none of its deps "
                         f"{spec['deps']} covers them: add the file or its folder")


def test_non_python_files_in_packages_are_package_data():
    """A file the code reads from a package folder (SQL) ships with the package and counts as the code
    of the stages that import it; a stage whose deps missed it would be reported."""
    found = {p.relative_to(REPO) for package in PACKAGES for p in (REPO / package).rglob("*.sql")}  # views
    read = data_files(stage_modules(STAGES["store"]["cmd"]))
    assert found and sorted(p.as_posix() for p in found - read) == []
    without_pipeline = ["ingest", "sim", "metrics", "pipeline/stages"]
    assert uncovered(without_pipeline, read) == sorted(p.as_posix() for p in read)


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_stage_code_deps_are_only_the_code_it_runs(stage):
    spec = STAGES[stage]
    runs = stage_modules(spec["cmd"])
    extra = unneeded(spec["deps"], runs)
    assert not extra, (f"dvc.yaml stage {stage!r} (`{spec['cmd']}`) depends on {extra}, which its command "
                       f"never imports: a change there would rerun it for nothing. Its code deps: "
                       f"{code_deps(runs)}")


def test_a_metrics_module_reruns_only_the_stages_that_import_it():
    """metrics/spm.py (SPM1D) is run by the metrics, store and report stages (the store's tables and
    the report's titles come from the metric tables' registry), the bench that times them and the
    transfer gate (its SPM checks; `adopted` runs the transfer command), and by nothing upstream of
    them or the studies."""
    spm = Path("metrics/spm.py")
    running = {name for name, st in STAGES.items() if not uncovered(st["deps"], [spm])}
    assert "metrics" in running
    assert running <= {"metrics", "store", "report", "summary", "bench", "transfer", "adopted"}, running


def test_broken_dvc_yaml_is_reported():
    """The check fails on a copy of dvc.yaml whose simulate stage lost its sim deps."""
    broken = copy.deepcopy(load_dvc_yaml())
    sim_stage = broken["stages"]["simulate"]["do"]
    sim_stage["deps"] = [d for d in sim_stage["deps"] if not (d == "sim" or d.startswith("sim/"))]

    found = problems(broken)

    runs = stage_modules(STAGES["simulate"]["cmd"])
    sim_modules = sorted(p.as_posix() for p in runs if p.parts[0] == "sim")
    assert list(found) == ["simulate"], found
    assert found["simulate"] == sim_modules
    assert {"sim/__init__.py", "sim/errors.py"} <= set(found["simulate"])

    broad = copy.deepcopy(load_dvc_yaml())  # the ingest stage depending on the whole metrics package
    broad["stages"]["ingest"]["do"]["deps"].append("metrics")
    found = problems(broad)
    assert list(found) == ["ingest"], found
    assert "unneeded metrics/spm.py" in found["ingest"] and "unneeded metrics/__init__.py" in found["ingest"]


def test_stage_modules_follow_function_imports_and_packages():
    runs = {p.as_posix() for p in stage_modules("python -m pipeline reference camargo")}
    # cmd_reference imports pipeline.stages.reference inside the function; load_human_model is
    # imported inside a function of that module; `import sim.x` runs sim/__init__.py
    assert {"pipeline/__init__.py", "pipeline/__main__.py", "pipeline/cli.py", "pipeline/stages/__init__.py",
            "pipeline/stages/reference.py", "sim/__init__.py", "sim/body/human.py"} <= runs
    # another command's lazy import (cmd_render's) is not this command's code
    assert "pipeline/commands/render.py" not in runs


def test_report_templates_count_as_the_report_stages_code():
    """The templates are package data of pipeline.report: a report stage whose deps name its
    modules but not the templates folder is reported."""
    folder = REPO / "pipeline" / "report" / "templates"
    templates = sorted(p.relative_to(REPO).as_posix() for p in folder.glob("*.j2"))
    assert {f"pipeline/report/templates/{t}" for t in ("index.html.j2", "subject.md.j2")} <= set(templates)
    for stage in ("report", "summary"):
        assert set(templates) <= {p.as_posix() for p in stage_files(STAGES[stage]["cmd"])}
    cmd = STAGES["summary"]["cmd"]
    narrowed = [d for d in STAGES["summary"]["deps"] if d not in ("pipeline", "pipeline/report",
                                                                  "pipeline/report/templates")] + [
        m.as_posix() for m in stage_modules(cmd)]  # every module it runs, file by file, and no template
    assert [f for f in uncovered(narrowed, stage_files(cmd)) if not f.endswith(".sql")] == templates


def test_code_deps_and_unneeded():
    mods = [Path("metrics/__init__.py"), Path("metrics/spm.py"), Path("pipeline/params.py")]
    assert code_deps(mods) == ["metrics/__init__.py", "metrics/spm.py", "pipeline/params.py"]
    every = sorted(p.as_posix() for p in python_files(PurePosixPath("metrics")))
    assert code_deps(every) == ["metrics"]
    assert unneeded(["metrics/spm.py", "data/x.yaml"], mods) == []
    extra = unneeded(["metrics"], mods)
    assert "metrics/gait.py" in extra and "metrics/spm.py" not in extra


def test_uncovered():
    mods = [Path("sim/robot/mrba.py"), Path("sim/errors.py"), Path("pipeline/params.py")]
    assert uncovered(["sim/robot", "pipeline/params.py", "data/x.yaml"], mods) == ["sim/errors.py"]
    assert uncovered(["sim/", "./pipeline"], mods) == []
    assert uncovered(["sim/rob", "sim/errors"], mods) == ["pipeline/params.py", "sim/errors.py",
                                                           "sim/robot/mrba.py"]
    assert uncovered([], [REPO / "sim" / "errors.py"]) == ["sim/errors.py"]
