"""The static (scaling) trial of a subject, read: the standing pose's marker positions and IK
angles, and the landmark roles that name its markers.

Markers are the median over the static window (`static.window_s` of the subject file; the whole
file without one), Z up (the declared up axis turned to Z), lab axes and origin otherwise. Angles
are the median of `static.angles` (the dataset's IK of the static pose, canonical names and signs,
degrees) over the same window, plus `subtalar_left` / `subtalar_right` when the file has OpenSim's
subtalar coordinates (not canonical angles; the model folds them into its ankle hinge); none when
the subject file names no static angles. Roles are the subject's marker set plus the static-only
landmarks of `data/markersets/scaling/<markerset>.yaml` (absent file: none).
`sim.body.scaling.scale_subject` turns a `StaticTrial` into the scaled body.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ingest.canonical import canonical_angles, up_to_z
from ingest.errors import SubjectError
from ingest.manifest import Manifest
from ingest.readers import read_markers, read_mot
from ingest.subject import MARKERSETS_DIR, Subject
from ingest.trial import SIDES

SCALING_ROLES_DIR = MARKERSETS_DIR / "scaling"


@dataclass(frozen=True)
class StaticTrial:
    """A subject's static trial as arrays (module docstring).

    markers: marker name -> (3,) position (m); angles_deg: canonical angle name -> degrees ({} without
    static angles); roles: landmark role -> marker name; source / angles_source: the files read
    (errors name them)."""

    subject: str
    markers: dict[str, np.ndarray]
    roles: dict[str, str]
    source: str
    angles_deg: dict[str, float] = field(default_factory=dict)
    angles_source: str | None = None


def scaling_roles(subject: Subject, directory: Path = SCALING_ROLES_DIR) -> dict[str, str]:
    """The subject's landmark roles: its marker set plus the static-only ones in
    `data/markersets/scaling/<markerset>.yaml` (absent file: none)."""
    roles = dict(subject.markerset)
    name = None
    if subject.path is not None and subject.path.is_file():
        name = (yaml.safe_load(subject.path.read_text()) or {}).get("markerset")
    path = directory / f"{name}.yaml"
    if name and path.is_file():
        roles.update({str(k): str(v) for k, v in (yaml.safe_load(path.read_text()) or {}).items()})
    return roles


def static_markers(path: Path, subject: Subject) -> dict[str, np.ndarray]:
    """Median marker positions of the static file `path` over the subject's static window, Z up
    (lab axes otherwise); markers without a finite median are left out."""
    table = read_markers(path)
    xyz = up_to_z(table.xyz_m, subject.format.up_axis)
    if subject.static.window_s is not None:
        t0, t1 = subject.static.window_s
        keep = (table.time_s >= t0) & (table.time_s <= t1)
        if keep.sum() < 2:
            raise SubjectError(path, f"static window {t0}-{t1} s holds {keep.sum()} frames")
        xyz = xyz[keep]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(xyz, axis=0)
    return {n: med[j] for j, n in enumerate(table.names) if np.isfinite(med[j]).all()}


def static_ik_angles(path: Path, subject: Subject) -> dict[str, float]:
    """The dataset's IK angles of the static pose in `path` (canonical names and signs, degrees,
    plus the subtalar angles): medians over the static window (whole file without a window)."""
    mot = read_mot(path)
    angles = canonical_angles(mot, subject.format, None)
    keep = np.ones(len(mot.time_s), bool)
    if subject.static.window_s is not None:
        t0, t1 = subject.static.window_s
        keep = (mot.time_s >= t0) & (mot.time_s <= t1)
    if keep.sum() < 1:
        raise SubjectError(path, f"static window {subject.static.window_s} s holds no IK frames")
    out = {k: float(np.nanmedian(v[keep])) for k, v in angles.items()}
    in_degrees = mot.in_degrees if mot.in_degrees is not None else subject.format.angle_unit == "deg"
    for side in SIDES:  # not a canonical angle: the model folds it into its ankle hinge
        column = f"subtalar_angle_{side[0]}"
        if column in mot.table.columns:
            values = mot.table[column].to_numpy(float)[keep]
            out[f"subtalar_{side}"] = float(np.nanmedian(values if in_degrees else np.degrees(values)))
    return out


def read_static_trial(subject: Subject, manifest: Manifest,
                      roles_dir: Path = SCALING_ROLES_DIR) -> StaticTrial:
    """Read `subject`'s static trial (field `static` of the subject file)."""
    if subject.static is None:
        raise SubjectError(subject.path, "no static trial (field 'static') to scale the model from")
    path = manifest.resolve(subject.static.markers)
    markers, roles = static_markers(path, subject), scaling_roles(subject, roles_dir)
    if subject.static.angles is None:
        return StaticTrial(subject.id, markers, roles, str(path))
    angles_path = manifest.resolve(subject.static.angles)
    return StaticTrial(subject.id, markers, roles, str(path), static_ik_angles(angles_path, subject),
                       str(angles_path))
