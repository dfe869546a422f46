"""`sim.learn.train.train` as one Ray job: on this machine or on a node of the `RAY_ADDRESS` cluster
(`sim.rollout.cluster`). Kept apart from `sim.learn.train` so that training itself imports no Ray."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import ray

from sim.learn.train import PROGRESS_FILE, TrainParams, train
from sim.motion.reference import ReferenceCycle
from sim.rollout.cluster import connect


def _pack(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` by its relative path (a policy folder is a few MB)."""
    return {str(f.relative_to(folder)): f.read_bytes() for f in sorted(folder.rglob("*")) if f.is_file()}


def _unpack(folder: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


@ray.remote
def _train_job(human_xml: bytes, cycle: ReferenceCycle, p: TrainParams, policy: dict[str, bytes],
               init: dict[str, bytes] | None, kwargs: dict) -> tuple[dict[str, bytes], dict]:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "human.xml").write_bytes(human_xml)
        _unpack(root / "policy", policy)
        if init is not None:
            _unpack(root / "init", init)
        rec = train(root / "human.xml", cycle, p, root / "policy", init_from=root / "init" if init else None,
                    progress=False, **kwargs)
        return _pack(root / "policy"), rec


def train_on_ray(model_path: str | Path, cycle: ReferenceCycle, p: TrainParams, out_dir: str | Path, *,
                 cpus: int, init_from: str | Path | None = None, **kwargs: object) -> dict:
    """`train` as one Ray job of `cpus` CPUs: on this machine or on a node of the `RAY_ADDRESS`
    cluster (`sim.rollout.cluster`). The body, the policy to resume or start from and the resulting
    policy folder travel as bytes, so the node needs no shared disk; `out_dir` is written only when
    the job succeeded (a failed job leaves the committed policy as it was)."""
    connect(cpus)
    out = Path(out_dir)
    policy = _pack(out) if kwargs.get("resume") and out.is_dir() else {}
    init = _pack(Path(init_from)) if init_from is not None else None
    files, rec = ray.get(_train_job.options(num_cpus=cpus).remote(Path(model_path).read_bytes(), cycle, p,
                                                                   policy, init, kwargs))
    if init_from is not None and "initialised_from" in rec:  # name the real start, not the job's copy
        rec["initialised_from"] = str(init_from)
        files[PROGRESS_FILE] = (json.dumps(rec, indent=2) + "\n").encode()
    out.mkdir(parents=True, exist_ok=True)
    _unpack(out, files)
    return rec


__all__ = ["train_on_ray"]
