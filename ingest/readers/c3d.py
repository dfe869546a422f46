"""C3D files (Vicon, Qualisys, ...), read with ezc3d.

Points come in the unit of `POINT:UNITS` (usually mm) and are converted to metres; force
platforms, when present, are read through ezc3d's force-platform extraction (N, and mm for the
centre of pressure).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ingest.errors import IngestError
from ingest.readers.table import UNIT_TO_M, MarkerTable


@dataclass(frozen=True)
class C3dRecording:
    markers: MarkerTable
    plate_force_n: np.ndarray | None  # (n_frames_analog, n_plates, 3), lab axes
    plate_cop_m: np.ndarray | None
    plate_rate_hz: float | None


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
    names = tuple(str(n).strip() for n in point["LABELS"]["value"])
    pts = np.asarray(c3d["data"]["points"][:3], dtype=float)  # (3, n_markers, n_frames)
    xyz = np.transpose(pts, (2, 1, 0)) * UNIT_TO_M[unit]
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
