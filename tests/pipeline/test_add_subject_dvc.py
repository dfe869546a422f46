"""add-subject in a git + DVC clone: the new subject is committed without any path of this machine,
its new raw file is pushed to a DVC remote, and a second clone pulls it and rebuilds the subject.

The first clone is of this repository's committed state with this checkout's working tree laid over it
and committed (changed and new files, uncommitted ones included, so code and params agree with the code
under test). Commands run with this interpreter (the venv's) in the clone, so `python -m pipeline`
there imports the clone's code.
"""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

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
ENV = {**os.environ, "DVC_NO_ANALYTICS": "1", "OMP_NUM_THREADS": "1", "GAITLOOP_MIRROR": str(DATA),
       "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
       "GIT_COMMITTER_EMAIL": "t@t", "GIT_CONFIG_NOSYSTEM": "1"}


def sh(cwd: Path, *cmd: str, timeout: float = 120) -> str:
    done = subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(cmd)} failed in {cwd}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def dvc(cwd: Path, *args: str) -> str:
    return sh(cwd, sys.executable, "-m", "dvc", *args)


def clone(source: Path, dest: Path, remote: Path) -> Path:
    sh(dest.parent, "git", "clone", "-q", str(source), str(dest))
    dvc(dest, "config", "--local", "core.analytics", "false")
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


def test_added_subject_is_tracked_with_dvc_and_rebuilds_in_another_clone(tmp_path):
    remote = tmp_path / "remote"
    repo = clone(ROOT, tmp_path / "repo", remote)
    lay_working_tree_over(repo)

    lab = tmp_path / "lab"  # a new walk (another header: unknown to the manifest) and opencap4's static
    lab.mkdir()
    lines = (OC / "MarkerData" / "walking2.trc").read_text().splitlines(keepends=True)
    (lab / "lab_walk.trc").write_text("PathFileType\t4\t(X/Y/Z)\tlab_walk.trc\n" + "".join(lines[1:]))
    shutil.copy(OC / "MarkerData" / "static1.trc", lab / "lab_static.trc")
    walk_sha = sha256_of(lab / "lab_walk.trc")
    add_subject(SUBJECT, 1.68, 62.6, lab / "lab_static.trc",
                [NewTrial("free", lab / "lab_walk.trc", OC / "IK" / "walking2_ik.mot")],
                markerset="opencap_labval", up_axis="y", dataset="lab", registry=Registry.of_repo(repo, DATA))

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
