"""Which trained walking policy should a new subject start from? The nearest body and gait.

A policy is bound to the body and reference cycle it was trained on (`sim.learn.train.save_body`);
fine-tuning it on another subject works best when that subject is built and walks alike. Each body
is summarised by four numbers (`BodyFeatures`): standing height (static pose), total mass, leg
length (thigh + shank, mean of both sides, static pose) and preferred speed (the reference cycle's,
built from the subject's kept real strides). The distance between two bodies is the weighted RMS of
the natural-log ratios of those numbers: scale-free and symmetric, so 10 % taller counts as much as
10 % heavier or 10 % faster, and a distance of 0.1 is about a 10 % difference overall.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Annotated, Literal

import mujoco
from pydantic import BaseModel, ConfigDict, Field, with_config

from sim.body.human import standing_height
from sim.errors import SimulationError
from sim.learn.bodies import leg_length

NonNegative = Annotated[float, Field(ge=0.0)]


@dataclass(frozen=True)
class BodyFeatures:
    """What makes one walking body like another (module docstring)."""

    height_m: float
    mass_kg: float
    leg_length_m: float
    speed_mps: float


@with_config(extra="forbid")
@dataclass(frozen=True)
class FeatureWeights:
    """Weight of each feature's log ratio in the distance (`transfer.weights` of params.yaml)."""

    height: NonNegative = 1.0
    mass: NonNegative = 1.0
    leg_length: NonNegative = 1.0
    speed: NonNegative = 1.0

    def __post_init__(self) -> None:
        if not any(v > 0 for v in asdict(self).values()):
            raise ValueError("at least one weight must be positive")


@dataclass(frozen=True)
class NearestPolicy:
    """The chosen source policy, its distance and every candidate's distance (ascending)."""

    source: str
    distance: float
    distances: dict[str, float]


def body_features(model_path: str | Path, speed_mps: float) -> BodyFeatures:
    """Features of the scaled human in `model_path` (its `static` keyframe when it has one, else
    the joint-zero pose) walking at `speed_mps`."""
    model = mujoco.MjModel.from_xml_path(str(model_path))
    data = mujoco.MjData(model)
    if model.nkey and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "static") >= 0:
        mujoco.mj_resetDataKeyframe(model, data, model.key("static").id)
    mujoco.mj_kinematics(model, data)
    return BodyFeatures(standing_height(model, data), float(model.body_mass.sum()), leg_length(model),
                        float(speed_mps))


def log_ratios(a: BodyFeatures, b: BodyFeatures) -> dict[str, float]:
    """ln(a / b) per feature (weight names: height, mass, leg_length, speed)."""
    out = {}
    for f in fields(BodyFeatures):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if not (x > 0 and y > 0):
            raise SimulationError(f.name, f"features must be positive to compare bodies (got {x} and {y})")
        out[f.name.rsplit("_", 1)[0]] = math.log(x / y)
    return out


def feature_distance(a: BodyFeatures, b: BodyFeatures, w: FeatureWeights = FeatureWeights()) -> float:
    """Weighted RMS of the features' log ratios (module docstring)."""
    weights = asdict(w)
    total = sum(weights.values())
    if total <= 0:
        raise SimulationError("transfer.weights", "at least one feature weight must be positive")
    return math.sqrt(sum(weights[k] * r * r for k, r in log_ratios(a, b).items()) / total)


def nearest_policy(target: BodyFeatures, candidates: Mapping[str, BodyFeatures],
                   w: FeatureWeights = FeatureWeights()) -> NearestPolicy:
    """The candidate nearest `target` (ties: the first in name order)."""
    if not candidates:
        raise SimulationError("transfer", "no trained policy to start from")
    distances = {name: feature_distance(target, f, w) for name, f in sorted(candidates.items())}
    ranked = dict(sorted(distances.items(), key=lambda kv: kv[1]))
    source = next(iter(ranked))
    return NearestPolicy(source, ranked[source], ranked)


__all__ = ["BodyFeatures", "FeatureWeights", "NearestPolicy", "body_features", "feature_distance",
           "log_ratios", "nearest_policy"]


class TransferBench(BaseModel):
    """`python -m pipeline bench --only transfer`: the stage's procedure, timed, on a body no policy
    saw: `subject`'s recordings scaled geometrically by `scale` (pipeline/bench/transfer.py)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    subject: str
    scale: Annotated[float, Field(gt=0.0)]  # every length x this, mass x its cube
    max_wall_s: Annotated[float, Field(gt=0.0)]  # the bench run's budget (s)


class TransferSection(BaseModel):
    """The `transfer` section of params.yaml (`transfer@<subject>`, pipeline/stages/transfer.py):
    the universal policy (gated zero-shot first) or the nearest committed one, fine-tuned within a
    budget, gated every `chunk_steps`."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    subjects: tuple[str, ...]   # every subject of `subjects` without a committed policy (train.subjects)
    adopted: tuple[str, ...] = ()  # bundled subjects whose committed policy is the universal policy's
                                   # export that the adoption rule adopted (frozen stage adopted@<subject>)
    source: Literal["universal", "nearest"] = "universal"  # data/universal's policy, or the nearest committed
    steps: Annotated[int, Field(ge=1)]  # env steps of fine-tuning at most
    chunk_steps: Annotated[int, Field(ge=1)]  # gated after every this many
    max_wall_s: Annotated[float, Field(gt=0.0)]  # ... or this long in all (s)
    gate_seeds: Annotated[int, Field(ge=1)]  # walks per check of the gate
    gate: Literal["source", "all"]  # the checks its source policy passes, or all of them
    weights: FeatureWeights = FeatureWeights()
    bench: TransferBench
