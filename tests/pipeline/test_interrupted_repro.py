"""Issue 34 case 12: an interrupted `dvc repro` leaves each of the stage's outputs whole.

DVC deletes a stage's outputs before running its command unless they are `persist: true`; the
stages write all-or-nothing (`pipeline.stages.outputs.replacing`), so an output DVC leaves in
place is either the earlier one or the new one, never a half-written one. The test runs this
project's dvc.yaml and code in a scratch DVC repository (no git), the cheapest stage
(`ingest@camargo`) with earlier outputs in place, and sends SIGINT to it, as Ctrl-C in a terminal
does, once the stage's command runs. Where the signal lands is up to the scheduler: an output
the command had already replaced is the new one, and it must read as a whole file.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GAITLOOP_MIRROR", ROOT.parent / "shared" / "data"))
COPIED = ("ingest", "sim", "metrics", "pipeline", "params.yaml", "dvc.yaml", "data/subjects",
          "data/sources.yaml", "data/markersets")
pytestmark = pytest.mark.skipif(importlib.util.find_spec("dvc") is None, reason="DVC is not installed")


def stage_outputs(stage: str, item: str) -> list[str]:
    """Every output (outs, metrics, plots) of the foreach stage `stage` of this project's dvc.yaml."""
    do = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"][stage]["do"]
    entries = [*do.get("outs", []), *do.get("metrics", []), *do.get("plots", [])]
    return [(e if isinstance(e, str) else next(iter(e))).replace("${item}", item) for e in entries]


def whole(path: Path) -> bool:
    """Whether `path` reads as a complete file of its kind (parquet, npz or JSON)."""
    try:
        if path.suffix == ".parquet":
            pq.read_table(path)
        elif path.suffix == ".npz":
            with np.load(path) as npz:
                [npz[k] for k in npz.files]
        else:
            json.loads(path.read_text())
    except Exception:  # any reader's error means a truncated or foreign file
        return False
    return True


def scratch_repo(dest: Path) -> Path:
    """This checkout's code, params and pipeline in a fresh DVC repository without git."""
    ignore = shutil.ignore_patterns("__pycache__")
    for name in COPIED:
        src = ROOT / name
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=ignore)
        else:
            shutil.copy2(src, dest / name)
    subprocess.run([sys.executable, "-m", "dvc", "init", "-q", "--no-scm"], cwd=dest, check=True)
    return dest


def test_sigint_during_a_stage_leaves_each_output_earlier_or_whole(tmp_path):
    repo = scratch_repo(tmp_path / "repo")
    earlier = {}
    for name in stage_outputs("ingest", "camargo"):
        path = repo / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"earlier {name}\n")
        earlier[name] = path.read_text()
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "GAITLOOP_MIRROR": str(DATA), "OMP_NUM_THREADS": "1",
           "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])}
    repro = [sys.executable, "-m", "dvc", "repro", "--single-item", "--force", "ingest@camargo"]
    run = subprocess.Popen(repro, cwd=repo, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True, start_new_session=True)  # its own process group, as a terminal's job
    try:
        seen = []
        for line in run.stdout:  # DVC has dealt with the outputs before it runs the command
            seen.append(line)
            if line.startswith("> python -m pipeline ingest camargo"):
                break
        assert seen and seen[-1].startswith("> python"), "".join(seen)
        os.killpg(run.pid, signal.SIGINT)  # Ctrl-C: DVC and the stage's command
        rest = run.communicate(timeout=120)[0]
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode != 0, "".join(seen) + rest  # interrupted, not finished
    missing = [name for name in earlier if not (repo / name).is_file()]
    assert missing == []
    broken = [name for name, text in earlier.items()
              if (repo / name).read_bytes() != text.encode() and not whole(repo / name)]
    assert broken == []
    leftovers = [p.name for p in (repo / "data/processed/camargo/real").iterdir() if p.name.startswith(".")]
    assert leftovers == []
