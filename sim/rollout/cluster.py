"""Ray, the engine every parallel rollout, sweep and tuning job runs on.

`connect` starts a local Ray instance with the CPU count from params (`ray.num_cpus`) or, when
`RAY_ADDRESS` is set, joins that cluster (then the cluster's CPUs count). It is idempotent: a
process connects once. Workers get one BLAS/OpenMP thread each (Ray's default for 1-CPU tasks), so
two workers on two cores do not oversubscribe them.

A rollout job is a pure function of its inputs (`sim.rollout.batch.RolloutJob` and its setup), so a
job Ray retries after a worker died gives the same rows. `cached_worker` keeps one open world per
setup in each Ray worker process, so a process that runs many jobs of one subject compiles its
world once.
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
from collections.abc import Iterator
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


__all__ = ["RAY_ADDRESS", "cached_worker", "completed", "connect", "setup_key"]
