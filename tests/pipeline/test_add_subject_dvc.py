"""add-subject in a git + DVC clone: the new subject is committed without any path of this machine,
its new raw file is pushed to a DVC remote, and a second clone pulls it and rebuilds the subject; or
(issue 12) `dvc repro` builds the subject's own stages, `dvc status` is clean after, and a second clone
sharing the first one's DVC cache rebuilds them to the same output hashes.

The first clone is of this repository's committed state with this checkout's working tree laid over it
and committed (changed and new files, uncommitted ones included, so code and params agree with the code
under test). Commands run with this interpreter (the venv's) in the clone, so `python -m pipeline`
there imports the clone's code.
"""

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from ingest.manifest import Manifest, sha256_of
from ingest.subject import load_subject
from pipeline.commands.add_subject import NewTrial, Registry, add_subject

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GAITLOOP_MIRROR", ROOT.parent / "shared" / "data"))
OC = DATA / "opencap_labval_subject4"
SUBJECT = "labwalk"
TRACKED = f"data/raw/{SUBJECT}/lab_walk.trc"

pytestmark = [
    pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed"),
    pytest.mark.skipif(importlib.util.find_spec("dvc") is None, reason="DVC is not installed in this venv"),
    pytest.mark.skipif(not (ROOT / ".git").exists(), reason="not a git checkout: nothing to clone"),
    pytest.mark.skipif(not OC.is_dir(), reason=f"opencap4 files not in the mirror {DATA}"),
]
CHAIN = ("ingest", "scale", "reference", "simulate", "simulate_policy", "metrics")  # per-subject, in order
ENV = {**os.environ, "DVC_NO_ANALYTICS": "1", "OMP_NUM_THREADS": "1", "GAITLOOP_MIRROR": str(DATA),
       "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
       "GIT_COMMITTER_EMAIL": "t@t", "GIT_CONFIG_NOSYSTEM": "1", "MPLBACKEND": "Agg",
       # stages run `python -m pipeline ...`: this interpreter's, as `make run` puts .venv/bin first
       "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])}


def sh(cwd: Path, *cmd: str, timeout: float = 120) -> str:
    """`cmd`'s stdout; fails the test with its output when it exits non-zero."""
    done = subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(cmd)} failed in {cwd}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def dvc(cwd: Path, *args: str, timeout: float = 120) -> str:
    """This venv's DVC run in `cwd`."""
    return sh(cwd, sys.executable, "-m", "dvc", *args, timeout=timeout)


def clone(source: Path, dest: Path, remote: Path | None = None) -> Path:
    """A git clone of `source`, with `remote` (if any) as its default DVC remote in .dvc/config.local."""
    sh(dest.parent, "git", "clone", "-q", str(source), str(dest))
    dvc(dest, "config", "--local", "core.analytics", "false")
    if remote is not None:
        dvc(dest, "remote", "add", "--local", "-d", "local", str(remote))  # .dvc/config.local: not committed
    return dest


def lay_working_tree_over(repo: Path) -> None:
    """This checkout's tracked and untracked (not ignored) files as they are now, committed in `repo`."""
    listed = sh(ROOT, "git", "ls-files", "-z", "--cached", "--others", "--exclude-standard").split("\0")
    for name in filter(None, listed):
        src, dest = ROOT / name, repo / name
        if not src.is_file():
            dest.unlink(missing_ok=True)  # deleted here, not committed yet
        elif not dest.is_file() or dest.read_bytes() != src.read_bytes():
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest)
    sh(repo, "git", "add", "-A")
    sh(repo, "git", "commit", "-q", "--allow-empty", "-m", "this checkout's working tree")


def register_labwalk(repo: Path, lab: Path) -> str:
    """`add-subject` of SUBJECT in `repo` from a new walk (opencap4's walking2 under another header:
    unknown to the manifest, so DVC-tracked) and opencap4's static (the mirror's, reused); the walk's
    sha256."""
    lab.mkdir()
    lines = (OC / "MarkerData" / "walking2.trc").read_text().splitlines(keepends=True)
    (lab / "lab_walk.trc").write_text("PathFileType\t4\t(X/Y/Z)\tlab_walk.trc\n" + "".join(lines[1:]))
    shutil.copy(OC / "MarkerData" / "static1.trc", lab / "lab_static.trc")
    add_subject(SUBJECT, 1.68, 62.6, lab / "lab_static.trc",
                [NewTrial("free", lab / "lab_walk.trc", OC / "IK" / "walking2_ik.mot")],
                markerset="opencap_labval", up_axis="y", dataset="lab", registry=Registry.of_repo(repo, DATA))
    return sha256_of(lab / "lab_walk.trc")


def test_added_subject_is_tracked_with_dvc_and_rebuilds_in_another_clone(tmp_path):
    remote = tmp_path / "remote"
    repo = clone(ROOT, tmp_path / "repo", remote)
    lay_working_tree_over(repo)
    lab = tmp_path / "lab"
    walk_sha = register_labwalk(repo, lab)

    changed = sorted(line[3:] for line in sh(repo, "git", "status", "--porcelain", "-uall").splitlines())
    assert changed == [f"{TRACKED}.dvc", "data/sources.yaml", f"data/subjects/{SUBJECT}.yaml", "params.yaml"]
    assert sh(repo, "git", "check-ignore", TRACKED).strip() == TRACKED  # the data itself stays out of git
    added = [line[1:] for line in sh(repo, "git", "diff", "-U0").splitlines()
             if line.startswith("+") and not line.startswith("+++")]
    added += [(repo / p).read_text() for p in changed if not p.endswith(".yaml")]
    added.append((repo / "data" / "subjects" / f"{SUBJECT}.yaml").read_text())
    for text in added:  # no path of this machine in anything committed
        assert not any(s in text for s in ("file://", "/work", str(tmp_path), str(ROOT), str(DATA))), text
    listed = yaml.safe_load((repo / "data" / "sources.yaml").read_text())["files"]
    entry = listed[f"local/{SUBJECT}/lab_walk.trc"]
    assert entry == {"url": f"dvc:{TRACKED}", "path": TRACKED, "sha256": walk_sha,
                     "bytes": (lab / "lab_walk.trc").stat().st_size}

    sh(repo, "git", "add", "-A")
    sh(repo, "git", "commit", "-q", "-m", f"add subject {SUBJECT}")
    dvc(repo, "push", "-q", f"{TRACKED}.dvc")
    assert json.loads(dvc(repo, "status", "--json", f"{TRACKED}.dvc") or "{}") == {}
    assert json.loads(dvc(repo, "status", "--cloud", "--json", f"{TRACKED}.dvc") or "{}") == {}

    other = clone(repo, tmp_path / "other", remote)
    assert not (other / TRACKED).exists()
    dvc(other, "pull", "-q", f"{TRACKED}.dvc")
    manifest = Manifest.load(other / "data" / "sources.yaml", mirror=DATA, cache=other / "data" / "raw",
                             root=other)
    subject = load_subject(SUBJECT, other / "data" / "subjects")
    walk = manifest.resolve(subject.trials[0].markers)
    assert walk == other / TRACKED and sha256_of(walk) == walk_sha
    assert manifest.resolve(subject.static.markers).parent == OC / "MarkerData"  # listed: the mirror's

    probe = "import pipeline, ingest.manifest as m; print(pipeline.__file__); print(m.REPO_ROOT)"
    imported = sh(other, sys.executable, "-c", probe).split()
    assert imported == [str(other / "pipeline" / "__init__.py"), str(other)]
    sh(other, sys.executable, "-m", "pipeline", "ingest", SUBJECT, timeout=180)
    real = other / "data" / "processed" / SUBJECT / "real"
    assert (real / "strides.parquet").is_file() and (real / "summary.json").is_file()


def strings(node: Any) -> Iterator[str]:
    """Every key and scalar of a loaded YAML document, as text."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield str(key)
            yield from strings(value)
    elif isinstance(node, list):
        for value in node:
            yield from strings(value)
    elif node is not None:
        yield str(node)


def assert_no_machine_path(name: str, text: str, *places: Path) -> None:
    """No absolute path, `file://` URL, nor any of `places` (the clone, the mirror, home, temp) in
    committed YAML: each clone resolves the subject from relative paths and manifest keys only."""
    marks = ["file://", *{str(p) for p in (*places, Path.home(), Path(tempfile.gettempdir()))}]
    found = [m for m in marks if m in text]
    found += [v for v in strings(yaml.safe_load(text)) if os.path.isabs(v) or re.match(r"[A-Za-z]:[\\/]", v)]
    assert not found, f"{name} holds paths of this machine: {found}"


def stages_of(subject: str) -> list[str]:
    """`subject`'s stage chain as DVC names it (`ingest@labwalk` ...)."""
    return [f"{stage}@{subject}" for stage in CHAIN]


def cached_outs(repo: Path, subject: str) -> dict[str, str]:
    """md5 per output of `subject`'s chain that DVC caches, from `repo`'s dvc.lock: not the `cache: false`
    ones (metrics JSON with timings, provenance, report figures), which no clone can check out."""
    stages = yaml.safe_load((repo / "dvc.yaml").read_text())["stages"]
    lock = yaml.safe_load((repo / "dvc.lock").read_text())["stages"]
    cached = {(out if isinstance(out, str) else next(iter(out))).replace("${item}", subject)
              for stage in CHAIN for out in stages[stage]["do"]["outs"]
              if isinstance(out, str) or next(iter(out.values())).get("cache", True)}
    return {out["path"]: out["md5"] for stage in CHAIN for out in lock[f"{stage}@{subject}"]["outs"]
            if out["path"] in cached}


def repro(repo: Path, stages: list[str]) -> tuple[list[str], list[str]]:
    """`dvc repro --single-item STAGES` in `repo` (in the order given): the stages it ran and those it
    restored from the run-cache. Single items, as `dvc repro metrics@<id>` also walks up through
    `data/policies` into the frozen train and cohort stages of the other subjects (and fails there
    when the laid-over policies differ from dvc.lock, e.g. while a policy is being retrained)."""
    out = dvc(repo, "repro", "--single-item", *stages, timeout=600)
    return (re.findall(r"Running stage '([^']+)'", out),
            re.findall(r"Stage '([^']+)' is cached - skipping run", out))


def test_added_subject_repros_clean_and_another_clone_rebuilds_it_from_the_same_cache(tmp_path):
    """Issue 12: add-subject then `dvc repro` of the subject's own stages, ingest through metrics@<id>
    (`store` is global: it would need every subject's metrics and both sweeps), leaves `dvc status`
    clean and commits no machine path; a second clone whose `core.cache` is the first clone's cache
    (no remote) checks the raw file out and rebuilds the same output hashes."""
    repo = clone(ROOT, tmp_path / "repo")
    lay_working_tree_over(repo)
    walk_sha = register_labwalk(repo, tmp_path / "lab")
    chain = stages_of(SUBJECT)

    ran, restored = repro(repo, chain)
    assert ran == chain and restored == []
    assert json.loads(dvc(repo, "status", "--json", *chain, f"{TRACKED}.dvc") or "{}") == {}
    changed = sorted(line[3:] for line in sh(repo, "git", "status", "--porcelain", "-uall").splitlines())
    committed = ["dvc.lock", f"{TRACKED}.dvc", "data/sources.yaml", f"data/subjects/{SUBJECT}.yaml",
                 "params.yaml"]
    assert changed == sorted(committed)  # every output is ignored: in DVC's cache, or reports/
    tracked = sh(repo, "git", "ls-files", "--others", "--cached", "--exclude-standard", "*.dvc").split()
    assert f"{TRACKED}.dvc" in tracked
    for name in ["data/sources.yaml", f"data/subjects/{SUBJECT}.yaml", *tracked]:
        assert_no_machine_path(name, (repo / name).read_text(), tmp_path, repo, ROOT, DATA)
    lock = yaml.safe_load((repo / "dvc.lock").read_text())["stages"]
    entries = yaml.safe_dump({n: lock[n] for n in chain})
    assert_no_machine_path("dvc.lock", entries, tmp_path, repo, ROOT, DATA)
    built = cached_outs(repo, SUBJECT)
    assert {f"data/processed/{SUBJECT}/real/strides.parquet", f"data/processed/{SUBJECT}/model/human.xml",
            f"data/processed/{SUBJECT}/model/reference.npz", f"data/processed/{SUBJECT}/sim/strides.parquet",
            f"data/metrics/{SUBJECT}/tables"} <= built.keys(), built
    sh(repo, "git", "add", "-A")
    sh(repo, "git", "commit", "-q", "-m", f"add subject {SUBJECT}")

    other = clone(repo, tmp_path / "other")
    dvc(other, "cache", "dir", "--local", str(repo / ".dvc" / "cache"))  # .dvc/config.local: not committed
    assert not (other / TRACKED).exists()
    dvc(other, "checkout", f"{TRACKED}.dvc")  # from the shared cache: no remote configured
    assert sha256_of(other / TRACKED) == walk_sha
    ran, restored = repro(other, chain)
    assert sorted(ran + restored) == sorted(chain), (ran, restored)
    assert json.loads(dvc(other, "status", "--json", *chain, f"{TRACKED}.dvc") or "{}") == {}
    assert cached_outs(other, SUBJECT) == built
