"""Fair controller tuning: one procedure, one budget, one synthetic walk for every controller.

Each controller's free gains are searched by `scipy.optimize.minimize` (Nelder-Mead by default) with
the same number of rollouts, the same initial-simplex size (half a decade per gain, in log10 space,
so gains stay positive), the same seed and the same robot (command limits, latency, acceleration
limits are the robot's, identical for all). The walk is `sim.synthetic` (start from rest, 1.2 m/s,
intra-stride oscillation): never the evaluation data.

Objective (lower is better)::

    J = mean|e_x| + mean|e_y| + w * RMS(|F_harness|)      (m; w in m/N)

over the whole walk; a rollout that raises a fall, goes unstable or leaves NaN costs ``10 + J``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from sim.controllers import make_controller
from sim.controllers.adaptive import GAINS as ADAPTIVE_GAINS
from sim.controllers.pid import GAINS as PID_GAINS
from sim.replay import ReplayHuman, ReplayParams
from sim.robot import RobotParams
from sim.rollout import RolloutParams, RolloutResult, build_world, robot_info, rollout
from sim.synthetic import WalkParams, capsule_world, synthetic_walk

# Gains searched per controller class, and whether they are stored as log10 already.
SEARCHED = {"pid": (PID_GAINS, False), "adaptive": (ADAPTIVE_GAINS, True)}


@dataclass(frozen=True)
class TuningParams:
    """params `robot.tuning`."""

    method: str = "Nelder-Mead"
    max_evaluations: int = 90
    seed: int = 0
    force_weight_m_per_n: float = 0.001
    sample_rate_hz: float = 100.0
    walk: WalkParams = field(default_factory=WalkParams)

    @classmethod
    def from_dict(cls, d: dict) -> TuningParams:
        return cls(method=str(d["method"]), max_evaluations=int(d["max_evaluations"]), seed=int(d["seed"]),
                   force_weight_m_per_n=float(d["force_weight_m_per_n"]),
                   sample_rate_hz=float(d["sample_rate_hz"]),
                   walk=WalkParams(**{k: float(v) for k, v in d["walk"].items()}))


@dataclass(frozen=True)
class TuningResult:
    name: str
    gains: dict
    objective: float
    initial_objective: float
    n_evaluations: int
    wall_s: float
    metrics: dict


def score(result: RolloutResult, force_weight_m_per_n: float) -> tuple[float, dict]:
    """The tuning objective of one rollout and its parts."""
    df = result.robot
    f = np.sqrt((df[["harness_fx_n", "harness_fy_n", "harness_fz_n"]].to_numpy() ** 2).sum(axis=1))
    m = {"mean_abs_e_x_m": float(df.e_x_m.abs().mean()), "mean_abs_e_y_m": float(df.e_y_m.abs().mean()),
         "force_rms_n": float(np.sqrt(np.mean(f**2))), "fall": bool(df.fall.any()), "stable": result.stable}
    j = m["mean_abs_e_x_m"] + m["mean_abs_e_y_m"] + force_weight_m_per_n * m["force_rms_n"]
    if not np.isfinite(j):
        j = 1e3
    if m["fall"] or not m["stable"]:
        j += 10.0
    return float(j), m


def _to_x(gains: dict, names: tuple[str, ...], is_log: bool) -> np.ndarray:
    v = np.array([float(gains[n]) for n in names])
    return v if is_log else np.log10(v)


def _to_gains(x: np.ndarray, base: dict, names: tuple[str, ...], is_log: bool) -> dict:
    out = dict(base)
    out.update({n: float(v if is_log else 10.0**v) for n, v in zip(names, x, strict=True)})
    return out


def evaluate(spec: dict, robot: RobotParams, replay: ReplayParams, p: TuningParams) -> tuple[float, dict]:
    """Objective of a controller entry ``{class, gains}`` on the synthetic walk."""
    rp = RolloutParams(robot=robot, sample_rate_hz=p.sample_rate_hz)
    human = ReplayHuman(synthetic_walk(p.walk), replay)
    world = capsule_world(p.walk.mass_kg, p.walk.pelvis_height_m)
    ctrl = make_controller(spec, robot_info(robot, p.sample_rate_hz))
    return score(rollout(world, human, ctrl, rp, p.seed), p.force_weight_m_per_n)


def tune(name: str, spec: dict, robot: RobotParams, replay: ReplayParams, p: TuningParams) -> TuningResult:
    """Search the gains of controller `name` (class in `spec`) from `spec['gains']` within the budget."""
    names, is_log = SEARCHED[spec["class"]]
    rp = RolloutParams(robot=robot, sample_rate_hz=p.sample_rate_hz)
    human = ReplayHuman(synthetic_walk(p.walk), replay)
    world = capsule_world(p.walk.mass_kg, p.walk.pelvis_height_m)
    model = build_world(world, human, rp)
    info = robot_info(robot, p.sample_rate_hz)
    base = dict(spec.get("gains", {}))

    def cost(x: np.ndarray) -> float:
        ctrl = make_controller({"class": spec["class"], "gains": _to_gains(x, base, names, is_log)}, info)
        return score(rollout(world, human, ctrl, rp, p.seed, model=model), p.force_weight_m_per_n)[0]

    x0 = _to_x(base, names, is_log)
    start = time.perf_counter()
    j0 = cost(x0)
    simplex = np.vstack([x0, x0 + 0.5 * np.eye(len(x0))])
    options = {"maxfev": p.max_evaluations - 1, "xatol": 1e-3, "fatol": 1e-5}
    if p.method == "Nelder-Mead":
        options["initial_simplex"] = simplex
    res = minimize(cost, x0, method=p.method, options=options)
    gains = _to_gains(res.x, base, names, is_log)
    j, metrics = evaluate({"class": spec["class"], "gains": gains}, robot, replay, p)
    return TuningResult(name=name, gains=gains, objective=j, initial_objective=j0,
                        n_evaluations=int(res.nfev) + 1, wall_s=time.perf_counter() - start, metrics=metrics)
