"""Ray, the engine every parallel rollout, sweep and tuning job runs on.

`connect` starts a local Ray instance with the CPU count from params (`ray.num_cpus`) or, when
`RAY_ADDRESS` is set, joins that cluster (then the cluster's CPUs count). It is idempotent: a
process connects once. Workers get one BLAS/OpenMP thread each (Ray's default for 1-CPU tasks), so
two workers on two cores do not oversubscribe them.

A rollout job is a pure function of its inputs (`sim.rollout.batch.RolloutJob` and its setup), so a
job Ray retries after a worker died gives the same rows. `cached_worker` keeps one open world per
setup in each Ray worker process, so a process that runs many jobs of one subject compiles its
world once.

`local_head` keeps one local Ray instance up for a whole `dvc repro` (`python -m pipeline run`, what
`make run` calls): each stage then joins it in about a second instead of starting and stopping a
Ray of its own (about 7 s, 16 stages).
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import secrets
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import ray
from tqdm import tqdm

RAY_ADDRESS = "RAY_ADDRESS"
OBJECT_STORE_MB = 256  # rollout results are small; Ray's default (30 % of RAM) would idle a lot of memory
CACHED_WORLDS = 4      # open worlds a worker process keeps (a sweep's jobs come grouped by subject)
_CACHE: dict[str, Any] = {}


def connect(num_cpus: int) -> dict[str, float]:
    """Start (or join, via `RAY_ADDRESS`) Ray once per process; returns the cluster's resources."""
    if not ray.is_initialized():
        address = os.environ.get(RAY_ADDRESS) or "local"  # "local": a new instance, never a stray one
        kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": logging.ERROR,
                                  "log_to_driver": False}
        if address == "local":
            kwargs.update(num_cpus=int(num_cpus), object_store_memory=OBJECT_STORE_MB * 2**20)
        ray.init(address=address, **kwargs)
    return ray.cluster_resources()


@contextmanager
def local_head(num_cpus: int, cwd: Path, start_timeout_s: float = 90.0) -> Iterator[dict[str, str]]:
    """A Ray head node on this machine with `num_cpus` CPUs, up for the block: yields the environment
    variables that reach it (`RAY_ADDRESS` and the token Ray >= 2.59 asks of local clusters). Its
    workers start in `cwd`; the node and its workers are killed on leaving."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16), "RAY_USAGE_STATS_ENABLED": "0"}
    ray_cli = Path(sys.executable).with_name("ray")
    cmd = [str(ray_cli), "start", "--head", f"--port={port}", f"--num-cpus={int(num_cpus)}", "--block",
           "--node-ip-address=127.0.0.1", "--include-dashboard=false",
           f"--object-store-memory={OBJECT_STORE_MB * 2**20}"]
    full_env = {k: v for k, v in os.environ.items() if k != RAY_ADDRESS} | env
    head = subprocess.Popen(cmd, env=full_env, cwd=cwd, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    env[RAY_ADDRESS] = f"127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + start_timeout_s
        while not _head_up(ray_cli, env[RAY_ADDRESS], full_env):
            if head.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the local Ray head did not start ({' '.join(cmd)})")
            time.sleep(0.5)
        yield env
    finally:
        try:
            os.killpg(head.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        head.wait(timeout=30)
        _wait_port_closed(port, timeout_s=30.0)


def _wait_port_closed(port: int, timeout_s: float) -> None:
    """Wait until nothing listens on `port` any more: SIGKILL is delivered at once, but a busy machine
    may take a while to tear the GCS server down and close its socket (seen on a 2-core CI run). Gives
    up quietly after `timeout_s`: this runs while leaving the block, where raising would hide the
    block's own error."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
        except OSError:
            return
        time.sleep(0.1)


def _head_up(ray_cli: Path, address: str, env: dict[str, str]) -> bool:
    """Whether the head at `address` reports its CPUs (`ray status`)."""
    try:
        out = subprocess.run([str(ray_cli), "status", f"--address={address}"], env=env, capture_output=True,
                             text=True, timeout=60)
    except subprocess.TimeoutExpired:
        return False
    return out.returncode == 0 and any(ln.strip().endswith(" CPU") for ln in out.stdout.splitlines())


def completed(refs: list, desc: str = "", progress: bool = False) -> Iterator:
    """Each of the task references `refs` as soon as its task has finished (completion order), with a
    progress bar: the one wait loop of the batch runner, the sweep and the tuning."""
    pending = list(refs)
    with tqdm(total=len(pending), desc=desc, disable=not progress) as bar:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield from done
            bar.update(len(done))


def setup_key(setup: Any) -> str:
    """A digest of a picklable setup, naming its open world in a worker's cache."""
    return hashlib.sha256(pickle.dumps(setup)).hexdigest()[:16]


def cached_worker(setup: Any, make: Any) -> Any:
    """`make(setup)`, made once per setup and worker process."""
    key = setup_key(setup)
    if key not in _CACHE:
        while len(_CACHE) >= CACHED_WORLDS:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = make(setup)
    return _CACHE[key]


__all__ = ["RAY_ADDRESS", "cached_worker", "completed", "connect", "local_head", "setup_key"]
