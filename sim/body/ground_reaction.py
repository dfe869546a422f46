"""Ground reaction forces of the simulated human, per foot, as a force plate under each foot would
measure them: the force the floor exerts on the foot (world frame, N), its centre of pressure on
the floor (m) and the free moment about the vertical through it (N m).

Each foot's contacts with the floor plane (`sim.body.human`: 4 spheres and the foot's capsule) are
summed: F = sum f_i, CoP = sum(p_i f_iz) / sum(f_iz) (point contacts on a plane), free moment
T_z = sum((p_i - CoP) x f_i)_z. A foot off the floor has F = 0, CoP = NaN.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.errors import SimulationError

SIDES = {"left": "foot_l", "right": "foot_r"}
FLOOR = "floor"


class GroundReactionProbe:
    """Records both feet's ground reaction at every output sample of a rollout (the rollout calls
    it with the model, data and sample index, samples in order); `arrays()` returns them per side
    as (force (n, 3), cop (n, 3), free moment (n,))."""

    def __init__(self, model: mujoco.MjModel) -> None:
        floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
        bodies = {s: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for s, b in SIDES.items()}
        if floor < 0 or min(bodies.values()) < 0:
            raise SimulationError("human model", f"ground reaction needs geom {FLOOR!r} and bodies "
                                  f"{', '.join(SIDES.values())}")
        self.floor = floor
        self.side_of_body = {b: k for k, b in enumerate(bodies.values())}
        self.force: list[np.ndarray] = []
        self.cop: list[np.ndarray] = []
        self.moment: list[np.ndarray] = []
        self._f6 = np.zeros(6)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        if k != len(self.force):
            raise SimulationError("ground reaction", f"sample {k} recorded out of order")
        force, cop_k, moment = np.zeros((2, 3)), np.full((2, 3), np.nan), np.zeros(2)
        forces: list[list[tuple[np.ndarray, np.ndarray]]] = [[], []]
        for i in range(data.ncon):
            c = data.contact[i]
            if c.geom1 == self.floor:
                other, sign = c.geom2, 1.0   # contact normal points from geom1 (floor) to geom2 (foot)
            elif c.geom2 == self.floor:
                other, sign = c.geom1, -1.0
            else:
                continue
            side = self.side_of_body.get(int(model.geom_bodyid[other]))
            if side is None:
                continue
            mujoco.mj_contactForce(model, data, i, self._f6)
            f_world = c.frame.reshape(3, 3).T @ self._f6[:3]  # force of geom1 on geom2, world frame
            forces[side].append((c.pos.copy(), sign * f_world))
        for side, items in enumerate(forces):
            if not items:
                continue
            p = np.array([q for q, _ in items])
            f = np.array([g for _, g in items])
            total = f.sum(axis=0)
            force[side] = total
            if total[2] > 1e-9:
                cop = (p * f[:, 2:3]).sum(axis=0) / total[2]
                cop[2] = p[:, 2].mean()
                cop_k[side] = cop
                r = p - cop
                moment[side] = float((r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]).sum())
        self.force.append(force)
        self.cop.append(cop_k)
        self.moment.append(moment)

    def arrays(self, first: int = 0) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per side (force, cop, free moment) from sample `first` on (a rollout's discarded lead-in
        comes first)."""
        f, c, m = (np.array(x[first:]).reshape(-1, 2, *shape) for x, shape in
                   ((self.force, (3,)), (self.cop, (3,)), (self.moment, ())))
        return {s: (f[:, k], c[:, k], m[:, k]) for k, s in enumerate(SIDES)}


__all__ = ["GroundReactionProbe", "SIDES"]
