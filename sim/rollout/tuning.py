"""Fair controller tuning: one procedure, one budget, one synthetic walk for every controller.

Each controller's searched gains (those its class declares with a `search` scale,
`sim.robot.controllers.gains`) are searched by `scipy.optimize.minimize` (Nelder-Mead by default) with
the same number of rollouts, the same initial-simplex size (half a decade per gain, in log10 space:
a `log` gain is searched as its log10, so it stays positive, a `linear` one is a log10 already), the
same seed and the same robot (command limits, latency, acceleration limits are the robot's, identical
for all). The walks are `sim.motion.synthetic` (start from rest, then a
constant pace with intra-stride oscillation): a normal pace (1.2 m/s, +-0.05 m/s surge at step
frequency, +-0.03 m/s at stride frequency) and a fast one (1.6 m/s, +-0.15 and +-0.06 m/s), so that
gains which only work for one gentle, perfectly symmetric gait are not chosen (a first version tuned
on the normal walk alone gave a lightly damped PID, resonant near stride frequency, that went
unstable on the real Camargo gait); never the evaluation data. The objective is the mean over the
walks.

Objective (lower is better)::

    J = mean|e_x| + mean|e_y| + w * RMS(|F_harness|) + w_lim * violations      (m; w in m/N)

over the whole walk, where `violations` is the fraction of control samples whose command exceeds
the robot's command limits (speed, yaw rate) plus the fraction whose command changes faster than
the drive's acceleration limits allow: the drive clips such commands, so a controller that leans on
clipping (bang-bang yaw, jumpy speed) is outside the limits and has no margin left for real gait.
A rollout that raises a fall, goes unstable or leaves NaN costs ``10 + J``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
import pandas as pd
import scipy  # scipy.optimize loads on first use
from pydantic import Field, with_config

from sim.motion.replay import ReplayHuman, ReplayParams
from sim.motion.synthetic import WalkParams, capsule_world, synthetic_walk
from sim.robot.controllers import make_controller, resolve
from sim.robot.controllers.gains import searched
from sim.robot.mrba import BaseParams, RobotParams
from sim.rollout.loop import RolloutParams, RolloutResult, rollout
from sim.rollout.world import build_world, robot_info


@with_config(extra="forbid")
@dataclass(frozen=True)
class TuningParams:
    """params `robot.tuning`: the synthetic-walk search of the controllers' gains (scipy method,
    objective evaluations at most, seed, the objective's weights in m/N and m, the walks' sample rate
    in Hz, the walks) and each controller's starting gains (`initial`: controller -> gain -> value)."""

    method: str = "Nelder-Mead"
    max_evaluations: int = 80
    seed: int = 0
    force_weight_m_per_n: float = 0.001
    limit_weight_m: float = 0.2
    sample_rate_hz: float = 100.0
    walks: Annotated[tuple[WalkParams, ...], Field(min_length=1)] = (WalkParams(),)
    initial: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def walk(self) -> WalkParams:
        return self.walks[0]


@dataclass(frozen=True)
class TuningResult:
    name: str
    gains: dict
    objective: float
    initial_objective: float
    n_evaluations: int
    wall_s: float
    metrics: dict


def limit_violations(robot: pd.DataFrame, base: BaseParams) -> float:
    """Fraction of samples commanding beyond the speed / yaw-rate limits plus the fraction whose
    command changes faster than the acceleration limits (summed over the two channels)."""
    dt = np.diff(robot["time_s"].to_numpy())
    v, w = robot["cmd_speed_mps"].to_numpy(), robot["cmd_yaw_rate_rps"].to_numpy()
    over = (np.abs(v) > base.max_speed_mps).mean() + (np.abs(w) > base.max_yaw_rate_rps).mean()
    fast = (np.abs(np.diff(v)) / dt > base.max_accel_mps2).mean() + \
        (np.abs(np.diff(w)) / dt > base.max_yaw_accel_rps2).mean()
    return float(over + fast)


def score(result: RolloutResult, force_weight_m_per_n: float, base: BaseParams | None = None,
          limit_weight_m: float = 0.0) -> tuple[float, dict]:
    """The tuning objective of one rollout and its parts."""
    df = result.robot
    f = np.sqrt((df[["harness_fx_n", "harness_fy_n", "harness_fz_n"]].to_numpy() ** 2).sum(axis=1))
    m = {"mean_abs_e_x_m": float(df.e_x_m.abs().mean()), "mean_abs_e_y_m": float(df.e_y_m.abs().mean()),
         "force_rms_n": float(np.sqrt(np.mean(f**2))), "fall": bool(df.fall.any()), "stable": result.stable}
    j = m["mean_abs_e_x_m"] + m["mean_abs_e_y_m"] + force_weight_m_per_n * m["force_rms_n"]
    if base is not None:
        m["limit_violations"] = limit_violations(df, base)
        j += limit_weight_m * m["limit_violations"]
    if not np.isfinite(j):
        j = 1e3
    if m["fall"] or not m["stable"]:
        j += 10.0
    return float(j), m


def _to_x(gains: dict, scales: dict[str, str]) -> np.ndarray:
    """The search coordinates of `gains`: log10 of a gain searched on a log scale, the value itself
    of one searched linearly (a log10 already), per the controller's declaration."""
    x = np.array([float(gains[n]) for n in scales])
    log = np.array([s != "linear" for s in scales.values()], dtype=bool)
    x[log] = np.log10(x[log])
    return x


def _to_gains(x: np.ndarray, base: dict, scales: dict[str, str]) -> dict:
    out = dict(base)
    out.update({n: float(v if s == "linear" else 10.0**v)
                for (n, s), v in zip(scales.items(), x, strict=True)})
    return out


def evaluate(spec: dict, robot: RobotParams, replay: ReplayParams, p: TuningParams) -> tuple[float, dict]:
    """Objective of a controller entry ``{class, gains}``: mean over the synthetic walks; the parts
    are reported per walk."""
    rp = RolloutParams(robot=robot, sample_rate_hz=p.sample_rate_hz)
    js, parts = [], {}
    for i, walk in enumerate(p.walks):
        human = ReplayHuman(synthetic_walk(walk), replay)
        world = capsule_world(walk.mass_kg, walk.pelvis_height_m)
        ctrl = make_controller(spec, robot_info(robot))
        j, m = score(rollout(world, human, ctrl, rp, p.seed), p.force_weight_m_per_n, robot.base,
                     p.limit_weight_m)
        js.append(j)
        parts[f"walk{i}_{walk.speed_mps:g}mps"] = m
    return float(np.mean(js)), parts


def tune(name: str, spec: dict, robot: RobotParams, replay: ReplayParams, p: TuningParams) -> TuningResult:
    """Search the gains of controller `name` (class in `spec`) from `spec['gains']` within the budget."""
    scales = {n: g.search for n, g in searched(resolve(spec["class"])).items()}  # the declared search
    rp = RolloutParams(robot=robot, sample_rate_hz=p.sample_rate_hz)
    cases = []
    for walk in p.walks:
        human = ReplayHuman(synthetic_walk(walk), replay)
        world = capsule_world(walk.mass_kg, walk.pelvis_height_m)
        cases.append((world, human, build_world(world, human, rp)))
    info = robot_info(robot)
    base = dict(spec.get("gains", {}))

    def cost(x: np.ndarray) -> float:
        gains = _to_gains(x, base, scales)
        js = []
        for world, human, model in cases:
            ctrl = make_controller({"class": spec["class"], "gains": gains}, info)
            result = rollout(world, human, ctrl, rp, p.seed, model=model)
            js.append(score(result, p.force_weight_m_per_n, robot.base, p.limit_weight_m)[0])
        return float(np.mean(js))

    x0 = _to_x(base, scales)
    start = time.perf_counter()
    j0 = cost(x0)
    simplex = np.vstack([x0, x0 + 0.5 * np.eye(len(x0))])
    options = {"maxfev": p.max_evaluations - 1, "xatol": 1e-3, "fatol": 1e-5}
    if p.method == "Nelder-Mead":
        options["initial_simplex"] = simplex
    res = scipy.optimize.minimize(cost, x0, method=p.method, options=options)
    gains = _to_gains(res.x, base, scales)
    j, metrics = evaluate({"class": spec["class"], "gains": gains}, robot, replay, p)
    return TuningResult(name=name, gains=gains, objective=j, initial_objective=j0,
                        n_evaluations=int(res.nfev) + 1, wall_s=time.perf_counter() - start, metrics=metrics)
