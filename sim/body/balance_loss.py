"""Scripted balance-loss events of the torque-driven human: trip, slip, collapse and push.

The MRBA's second job is catching a fall (Wang, Chan et al. ICRA 2025), so the simulated person
must be able to lose balance in the ways people do, at a known time:
- ``trip``: the swing foot is caught (a 3-D point constraint holds the foot where it is at the
  onset, as an obstacle would) for `duration_s`; `magnitude` is the constraint's time constant
  (s; MuJoCo's default 0.02 s lets the driven foot creep a few cm, an obstacle does not give);
- ``slip``: the stance foot's friction drops to `magnitude` (its geoms also win MuJoCo's
  friction mixing, which otherwise takes the larger of the two) for `duration_s`;
- ``collapse``: every motor's torque limit x `magnitude` for `duration_s` (a faint, a knee
  giving way everywhere at once);
- ``push``: a horizontal force of `magnitude` newtons on the pelvis, to the left of the commanded
  heading (negative: to the right), for `duration_s`.
The swing and stance feet are told apart by height at the onset (the higher foot swings). The
world is compiled per rollout, so the model changes (friction, torque limits) end with it; they
are undone at the event's end anyway so the rest of the walk is the normal one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import mujoco
import numpy as np

KINDS = ("trip", "slip", "collapse", "push")
TRIP_EQUALITY = "trip_{}"  # one inactive point constraint per foot, named after the foot body


@dataclass(frozen=True)
class BalanceLoss:
    """One event: `kind` (KINDS), `onset_s` in the walk's clock (None: not placed yet), how long it
    lasts and how strong it is (see the module docstring for `magnitude`'s unit per kind)."""

    kind: str
    duration_s: float
    magnitude: float
    onset_s: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"balance loss {self.kind!r}: not one of {', '.join(KINDS)}")
        if self.duration_s <= 0:
            raise ValueError(f"balance loss {self.kind}: duration_s must be positive")

    def at(self, onset_s: float) -> BalanceLoss:
        return replace(self, onset_s=float(onset_s))


def add_trip_constraints(spec: mujoco.MjSpec, feet: tuple[str, ...], timeconst_s: float) -> None:
    """Inactive point constraints foot -> world, one per foot body (activated by a trip), critically
    damped with time constant `timeconst_s`."""
    for foot in feet:
        spec.add_equality(type=mujoco.mjtEq.mjEQ_CONNECT, name=TRIP_EQUALITY.format(foot), name1=foot,
                          objtype=mujoco.mjtObj.mjOBJ_BODY, active=False, solref=[timeconst_s, 1.0])


def body_geoms(model: mujoco.MjModel, body: int) -> np.ndarray:
    """The geoms of `body` and of every body below it (a foot and its toes)."""
    below = {body}
    for b in range(body + 1, model.nbody):  # children come after their parents
        if model.body_parentid[b] in below:
            below.add(b)
    return np.flatnonzero(np.isin(model.geom_bodyid, sorted(below)))


class BalanceLossRun:
    """Applies one `BalanceLoss` to a running world: made once the world is reset, then
    `apply(model, data, t)` before every output sample."""

    def __init__(self, event: BalanceLoss, pelvis: int, feet: np.ndarray, feet_names: tuple[str, ...],
                 motors: np.ndarray, heading_at: Callable[[float], float]) -> None:
        self.e, self.pelvis, self.feet, self.names, self.motors = event, pelvis, feet, feet_names, motors
        self.heading_at = heading_at  # t -> commanded heading (rad)
        self.on = False
        self.done = False
        self.side: int | None = None   # the foot the event acted on (index into feet), for trip / slip
        self.saved: np.ndarray | None = None

    def _trip_equality(self, model: mujoco.MjModel) -> int:
        name = TRIP_EQUALITY.format(self.names[self.side])
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, name)

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData, t: float) -> None:
        e = self.e
        if self.done or e.onset_s is None or t < e.onset_s:
            return
        if not self.on:
            self._begin(model, data)
            self.on = True
        if t >= e.onset_s + e.duration_s:
            self._end(model, data)
            self.on, self.done = False, True

    def _begin(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        e, z = self.e, data.xpos[self.feet, 2]
        if e.kind == "trip":
            self.side = int(np.argmax(z))
            eq = self._trip_equality(model)
            model.eq_data[eq, :6] = 0.0
            model.eq_data[eq, 3:6] = data.xpos[self.feet[self.side]]  # the foot's origin, held where it is
            data.eq_active[eq] = 1
        elif e.kind == "slip":
            self.side = int(np.argmin(z))
            g = body_geoms(model, int(self.feet[self.side]))
            self.saved = np.column_stack([model.geom_friction[g, 0], model.geom_priority[g]])
            model.geom_friction[g, 0] = e.magnitude
            model.geom_priority[g] = 100
        elif e.kind == "collapse":
            self.saved = model.actuator_forcerange[self.motors].copy()
            model.actuator_forcerange[self.motors] *= e.magnitude
        else:
            h = self.heading_at(e.onset_s)
            data.xfrc_applied[self.pelvis, :2] = e.magnitude * np.array([-np.sin(h), np.cos(h)])

    def _end(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        e = self.e
        if e.kind == "trip":
            data.eq_active[self._trip_equality(model)] = 0
        elif e.kind == "slip":
            g = body_geoms(model, int(self.feet[self.side]))
            model.geom_friction[g, 0] = self.saved[:, 0]
            model.geom_priority[g] = self.saved[:, 1].astype(int)
        elif e.kind == "collapse":
            model.actuator_forcerange[self.motors] = self.saved
        else:
            data.xfrc_applied[self.pelvis, :2] = 0.0


def steady_onset(spans: list[tuple[str, float, float]], rng: np.random.Generator, jitter_s: float) -> float:
    """An onset in the middle of the first steady span of a command profile (`CommandProfile.spans`),
    moved by a seeded +-`jitter_s` so seeds meet the gait at different phases."""
    steady = [(a, b) for phase, a, b in spans if phase == "steady"]
    if not steady:
        raise ValueError("no steady phase in the scenario to place a balance-loss event in")
    a, b = steady[0]
    return 0.5 * (a + b) + float(rng.uniform(-jitter_s, jitter_s))
