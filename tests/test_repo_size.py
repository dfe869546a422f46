"""Committed files stay small (docs/policies.md, "Committed policies"): everything git tracks totals
at most 40 MiB, as `git ls-files -z | xargs -0 du -cb` counts it. Committed policies keep what
rollouts need (weights and observation statistics), not optimizer or discriminator state; experiment
checkpoints under data/candidates leave git (their JSON records stay)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MAX_TRACKED_BYTES = 40 * 2**20


def tracked_sizes(root: Path = REPO) -> dict[str, int]:
    """Bytes of each file git tracks under `root` (as the working tree has it; a tracked file deleted
    from the working tree counts 0); skips the test outside a git checkout."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    run = subprocess.run(["git", "-C", str(root), "ls-files", "-z"], capture_output=True)
    if run.returncode != 0:
        pytest.skip(f"{root} is not a git checkout")
    sizes = {}
    for name in run.stdout.decode("utf-8", "surrogateescape").split("\0"):
        if name:
            path = root / name
            sizes[name] = os.lstat(path).st_size if os.path.lexists(path) else 0
    return sizes


def test_tracked_files_total_at_most_40_mib():
    sizes = tracked_sizes()
    total = sum(sizes.values())
    largest = sorted(sizes.items(), key=lambda kv: -kv[1])[:10]
    shown = "\n".join(f"  {n:>10,d}  {name}" for name, n in largest)
    assert total <= MAX_TRACKED_BYTES, (
        f"git tracks {total:,d} bytes ({total / 2**20:.1f} MiB), more than "
        f"{MAX_TRACKED_BYTES / 2**20:.0f} MiB; the largest files:\n{shown}")

