"""C3D files (Vicon, Qualisys, ...), read with ezc3d.

Points come in the unit of `POINT:UNITS` (usually mm) and are converted to metres; force
platforms, when present, are read through ezc3d's force-platform extraction (N, and mm for the
centre of pressure). Point names are `POINT:LABELS` continued in `LABELS2`, `LABELS3`, ... (one
parameter holds at most 255).

Only markers are kept. A C3D's points also hold a model's outputs, which are not positions on the
body and, used as markers, wreck scaling and marker IK (the Plug-in Gait files of the moissenet
data: 61-74 mm marker RMS with them, 11-17 mm without). Left out:
- the points named in the point-type parameters (`POINT:ANGLES`, `FORCES`, `MOMENTS`, `POWERS`,
  `SCALARS`, `REACTIONS`, any other group `POINT:TYPE_GROUPS` names) and in `MODELED_MARKERS`
  (e.g. `CentreOfMassFloor`, a point on the floor);
- unlabelled trajectories (`*<n>`, Vicon's name for a reconstruction no marker was assigned to);
- Plug-in Gait's segment axes: the points `<seg>O`, `<seg>A`, `<seg>L`, `<seg>P` (origin and the
  ends of the anterior, lateral and proximal axes, e.g. `RFOO` ... `RFOP`), recognised as a complete
  set of the four; the right side's lateral axis points medially, 100 mm off the foot or shank.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ingest.errors import IngestError
from ingest.readers.table import UNIT_TO_M, MarkerTable

NON_MARKER_TYPES = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS", "REACTIONS", "MODELED_MARKERS")
SEGMENT_AXIS_SUFFIXES = "OALP"


@dataclass(frozen=True)
class C3dRecording:
    markers: MarkerTable
    plate_force_n: np.ndarray | None  # (n_frames_analog, n_plates, 3), lab axes
    plate_cop_m: np.ndarray | None
    plate_rate_hz: float | None


def _point_labels(point: dict, n_points: int, path: Path) -> tuple[str, ...]:
    """The points' names: `POINT:LABELS`, continued in `LABELS2`, `LABELS3`, ... (a C3D parameter holds
    at most 255 labels; Vicon writes the rest there)."""
    labels, k = list(point["LABELS"]["value"]), 2
    while len(labels) < n_points and f"LABELS{k}" in point:
        labels += list(point[f"LABELS{k}"]["value"])
        k += 1
    if len(labels) < n_points:
        raise IngestError(path, f"{n_points} points but {len(labels)} labels (POINT:LABELS, LABELS2, ...)")
    return tuple(str(n).strip() for n in labels[:n_points])


def _model_outputs(point: dict, names: tuple[str, ...]) -> set[str]:
    """The point names that are not markers (module docstring)."""
    groups = {*NON_MARKER_TYPES, *(str(g).strip() for g in point.get("TYPE_GROUPS", {}).get("value", []))}
    out = {str(n).strip() for g in groups if g in point and not g.startswith("LABELS")
           for n in point[g]["value"]}
    out |= {n for n in names if n.startswith("*")}
    present = set(names)
    out |= {n for n in names if len(n) > 1 and n[-1] in SEGMENT_AXIS_SUFFIXES
            and all(n[:-1] + c in present for c in SEGMENT_AXIS_SUFFIXES)}
    return out


def read_c3d(path: str | Path) -> C3dRecording:
    """Read markers (and force platforms when present) from a C3D file."""
    import ezc3d

    path = Path(path)
    if not path.is_file():
        raise IngestError(path, "file not found")
    try:
        c3d = ezc3d.c3d(str(path), extract_forceplat_data=True)
    except Exception as exc:  # ezc3d raises bare RuntimeError/IOError on malformed files
        raise IngestError(path, f"unreadable C3D ({exc})") from None
    point = c3d["parameters"]["POINT"]
    unit = str(point["UNITS"]["value"][0]).strip() if "UNITS" in point else "mm"
    if unit not in UNIT_TO_M:
        raise IngestError(path, f"unknown POINT:UNITS {unit!r}")
    rate = float(point["RATE"]["value"][0])
    pts = np.asarray(c3d["data"]["points"][:3], dtype=float)  # (3, n_markers, n_frames)
    names = _point_labels(point, pts.shape[1], path)
    outputs = _model_outputs(point, names)
    keep = [j for j, n in enumerate(names) if n not in outputs]
    names = tuple(names[j] for j in keep)
    xyz = np.transpose(pts[:, keep], (2, 1, 0)) * UNIT_TO_M[unit]
    first = int(c3d["header"]["points"]["first_frame"])
    time = (first + np.arange(xyz.shape[0])) / rate
    markers = MarkerTable(path, rate, time, names, xyz, unit)
    plates = c3d["data"].get("platform", [])
    if not plates:
        return C3dRecording(markers, None, None, None)
    force = np.stack([np.asarray(p["force"], float).T for p in plates], axis=1)
    cop = np.stack([np.asarray(p["center_of_pressure"], float).T for p in plates], axis=1)
    cop_unit = str(plates[0].get("unit_position", "mm")).strip()
    analog_rate = float(c3d["parameters"]["ANALOG"]["RATE"]["value"][0])
    return C3dRecording(markers, force, cop * UNIT_TO_M.get(cop_unit, 1e-3), analog_rate)
