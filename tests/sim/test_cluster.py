"""`local_head`, the Ray head `python -m pipeline run` keeps up for a whole `dvc repro`: a separate
process (as a stage is) reaches it through the environment it yields and gets its CPUs, and the
head is gone once the block is left."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from sim.rollout.cluster import RAY_ADDRESS, local_head

REPO = Path(__file__).resolve().parents[2]
TASK = """
import ray
from sim.rollout.cluster import connect
print(connect(1)["CPU"], ray.get(ray.remote(lambda: 6 * 7).remote()))
"""


def test_local_head_serves_another_process_and_is_gone_after():
    base = {k: v for k, v in os.environ.items() if k != RAY_ADDRESS}
    with local_head(1, REPO) as env:
        out = subprocess.run([sys.executable, "-c", TASK], env={**base, **env}, cwd=REPO, capture_output=True,
                             text=True, timeout=180)
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.split()[-2:] == ["1.0", "42"]  # the head's one CPU, not a new local Ray's
        address = env[RAY_ADDRESS]
    host, port = address.split(":")
    with pytest.raises(OSError):  # nothing listens on the head's port any more
        socket.create_connection((host, int(port)), timeout=5).close()
