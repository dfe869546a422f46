"""A canonical trial written as the files OpenSim users open: markers (.trc), joint coordinates
(.mot), ground reactions (.mot with its ExternalLoads .xml) and the robot log (.csv).

OpenSim's ground frame is Y up, X forward, Z to the right (Delp et al. 2007, IEEE TBME 54:1940):
canonical Z-up points go out through `ingest.canonical.z_up_to` (x, z, -y), the inverse of what the
readers apply to a Y-up file, so `add-subject ... --up-axis y` reads them back unchanged.
Coordinates use OpenSim's names and signs (`ingest.canonical.OPENSIM_COORDINATES`, knee flexion
positive as in Rajagopal et al. 2016 and OpenCap's model); the upper body (`UPPER_BODY`) follows
the same sequence (`sim.motion.retarget.joint_angles`) but is not checked against an OpenSim model.
The pelvis translations are the pelvis body origin (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.canonical import opensim_coordinates, z_up_to
from ingest.readers.mot import write_mot
from ingest.readers.robot_log import RobotLog, write_robot_log
from ingest.readers.trc import write_trc
from ingest.trial import Trial

UP_AXIS = "y"
KNEE_FLEXION_SIGN = 1
UPPER_BODY = {
    "lumbar_extension": ("lumbar_extension", 1.0), "lumbar_bending": ("lumbar_bending", 1.0),
    "lumbar_rotation": ("lumbar_rotation", 1.0),
    **{f"arm_{kind}_{s[0]}": (f"shoulder_{name}_{s}", 1.0) for s in ("left", "right")
       for kind, name in (("flex", "flexion"), ("add", "adduction"), ("rot", "rotation"))},
    **{f"elbow_flex_{s[0]}": (f"elbow_flexion_{s}", 1.0) for s in ("left", "right")},
}
FOOT_BODIES = {"right": "calcn_r", "left": "calcn_l"}  # OpenSim's foot bodies (gait2392, Rajagopal)


@dataclass(frozen=True)
class GroundReaction:
    """One foot's ground reaction, canonical frame: force on the foot (n, 3) N, centre of pressure
    (n, 3) m (NaN while unloaded) and free moment about the vertical (n,) N m."""

    force_n: np.ndarray
    cop_m: np.ndarray
    free_moment_nm: np.ndarray


@dataclass(frozen=True)
class ExportedTrial:
    markers: Path
    coordinates: Path
    grf: Path | None
    external_loads: Path | None
    robot_log: Path | None


def export_trial(folder: Path, trial: Trial, pelvis_m: np.ndarray | None = None,
                 ground: dict[str, GroundReaction] | None = None, robot: RobotLog | None = None
                 ) -> ExportedTrial:
    """Write `trial` (canonical frame) into `folder` as `<trial>.trc`, `<trial>_ik.mot` and, when
    given, `<trial>_grf.mot` + `<trial>_grf.xml` and `<trial>_robot.csv`."""
    folder.mkdir(parents=True, exist_ok=True)
    name = trial.trial
    names = tuple(trial.markers)
    xyz = np.stack([trial.markers[n] for n in names], axis=1) if names else np.zeros((trial.n_frames, 0, 3))
    trc = write_trc(folder / f"{name}.trc", trial.time_s, names, z_up_to(xyz, UP_AXIS))
    coords = {"time": trial.time_s,
              **opensim_coordinates(trial.angles, KNEE_FLEXION_SIGN, UPPER_BODY)}
    if pelvis_m is not None:
        tx, ty, tz = z_up_to(np.asarray(pelvis_m, float), UP_AXIS).T
        coords.update(pelvis_tx=tx, pelvis_ty=ty, pelvis_tz=tz)
    mot = write_mot(folder / f"{name}_ik.mot", pd.DataFrame(coords), f"{name} coordinates", in_degrees=True)
    grf = xml = None
    if ground is not None:
        grf = write_mot(folder / f"{name}_grf.mot", grf_table(trial.time_s, ground),
                        f"{name} ground reactions", in_degrees=False)
        xml = folder / f"{name}_grf.xml"
        xml.write_text(external_loads_xml(name, grf.name))
    log = None
    if robot is not None:
        log = folder / f"{name}_robot.csv"
        write_robot_log(log, robot)
    return ExportedTrial(trc, mot, grf, xml, log)


def grf_table(time_s: np.ndarray, ground: dict[str, GroundReaction]) -> pd.DataFrame:
    """OpenSim's GRF columns per foot (`r_`/`l_` prefixes): `<p>ground_force_v{x,y,z}` (N),
    `<p>ground_force_p{x,y,z}` (m, 0 while unloaded) and `<p>ground_torque_{x,y,z}` (N m), Y up."""
    cols: dict[str, np.ndarray] = {"time": np.asarray(time_s, float)}
    for side, g in ground.items():
        p = f"{side[0]}_"
        force = z_up_to(np.asarray(g.force_n, float), UP_AXIS)
        cop = z_up_to(np.nan_to_num(np.asarray(g.cop_m, float)), UP_AXIS)
        torque = np.zeros_like(force)
        torque[:, 1] = g.free_moment_nm  # the vertical is OpenSim's Y
        for j, a in enumerate("xyz"):
            cols[f"{p}ground_force_v{a}"] = force[:, j]
        for j, a in enumerate("xyz"):
            cols[f"{p}ground_force_p{a}"] = cop[:, j]
        for j, a in enumerate("xyz"):
            cols[f"{p}ground_torque_{a}"] = torque[:, j]
    return pd.DataFrame(cols)


def external_loads_xml(name: str, datafile: str) -> str:
    """OpenSim ExternalLoads applying each foot's GRF to its calcaneus, expressed in ground."""
    forces = "".join(
        f"""
      <ExternalForce name="{side}_grf">
        <applied_to_body>{body}</applied_to_body>
        <force_expressed_in_body>ground</force_expressed_in_body>
        <point_expressed_in_body>ground</point_expressed_in_body>
        <force_identifier>{side[0]}_ground_force_v</force_identifier>
        <point_identifier>{side[0]}_ground_force_p</point_identifier>
        <torque_identifier>{side[0]}_ground_torque_</torque_identifier>
        <data_source_name>{datafile}</data_source_name>
      </ExternalForce>""" for side, body in FOOT_BODIES.items())
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000">
  <ExternalLoads name="{name}_external_loads">
    <objects>{forces}
    </objects>
    <datafile>{datafile}</datafile>
  </ExternalLoads>
</OpenSimDocument>
"""


__all__ = ["ExportedTrial", "GroundReaction", "UPPER_BODY", "export_trial", "external_loads_xml", "grf_table"]
