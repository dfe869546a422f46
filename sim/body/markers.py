"""Virtual markers: the model's marker sites (named as the subject's real markers) read out of a
simulation, and simulated motion written as a canonical `ingest.trial.Trial` (source 'sim'), so
that `ingest.process.process_trial` treats it exactly as a real recording.

The simulation world is already canonical (Z up, metres); joint angles are the retargeting
definitions (`sim.motion.retarget.joint_angles`, degrees, canonical signs).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ingest.trial import Provenance, Trial
from sim.body.human import MARKER_SITE_GROUP
from sim.errors import SimulationError
from sim.motion.retarget import joint_angles

ROBOT_PREFIX = "mrba_"


def marker_sites(model: mujoco.MjModel) -> dict[str, int]:
    """Marker name -> site id of the human's virtual markers (site group `MARKER_SITE_GROUP`)."""
    out = {}
    for i in range(model.nsite):
        name = model.site(i).name
        if model.site_group[i] == MARKER_SITE_GROUP and name and not name.startswith(ROBOT_PREFIX):
            out[name] = i
    return out


def marker_positions(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, np.ndarray]:
    """Positions (3,) of every virtual marker in `data` (after mj_kinematics / mj_forward / mj_step)."""
    return {name: data.site_xpos[i].copy() for name, i in marker_sites(model).items()}


def marker_trajectories(model: mujoco.MjModel, qpos: np.ndarray) -> dict[str, np.ndarray]:
    """Marker name -> (n, 3) positions along the configurations `qpos` (n, nq)."""
    qpos = np.atleast_2d(np.asarray(qpos, float))
    if qpos.shape[1] != model.nq:
        raise SimulationError("human model", f"qpos has {qpos.shape[1]} columns, the model has "
                              f"nq = {model.nq}")
    sites = marker_sites(model)
    ids = np.array(list(sites.values()), int)
    data = mujoco.MjData(model)
    out = np.empty((len(qpos), len(ids), 3))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[k] = data.site_xpos[ids]
    return {name: out[:, j].copy() for j, name in enumerate(sites)}


def trial_from_qpos(model: mujoco.MjModel, qpos: np.ndarray, rate_hz: float, subject: str,
                    condition: str, trial: str, t0_s: float = 0.0,
                    provenance: tuple[Provenance, ...] = ()) -> Trial:
    """A canonical `Trial` (source 'sim') of the human moving through `qpos` (n, nq) sampled at
    `rate_hz`: every virtual marker and the canonical joint angles."""
    qpos = np.atleast_2d(np.asarray(qpos, float))
    if rate_hz <= 0:
        raise SimulationError(f"{subject}/{trial}", f"sampling rate must be positive, got {rate_hz}")
    time = t0_s + np.arange(len(qpos)) / rate_hz
    return Trial(subject, condition, "sim", trial, float(rate_hz), time,
                 marker_trajectories(model, qpos), joint_angles(model, qpos), None, provenance)
