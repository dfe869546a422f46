"""gaitloop's documented CSV layout, for data exported from any other tool.

One row per frame; columns (order free, names case-sensitive):

- ``time_s``: sample time in seconds (required, strictly increasing);
- ``<marker>_x_<unit>``, ``<marker>_y_<unit>``, ``<marker>_z_<unit>`` with unit ``m``, ``cm`` or
  ``mm``: marker positions in the file's lab axes (the up axis is declared in the subject file);
- ``<angle>_deg`` or ``<angle>_rad``: joint angles already in the canonical sign convention,
  named as in the canonical Trial (``hip_flexion_left``, ``knee_flexion_right``, ``pelvis_tilt``).

Empty cells are missing samples. Units are part of every column name, so nothing is guessed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import IngestError
from ingest.readers.table import UNIT_TO_M, MarkerTable

_MARKER = re.compile(r"^(?P<name>.+)_(?P<axis>[xyz])_(?P<unit>mm|cm|m)$")
_ANGLE = re.compile(r"^(?P<name>.+)_(?P<unit>deg|rad)$")


@dataclass(frozen=True)
class CsvRecording:
    markers: MarkerTable
    angles_deg: dict[str, np.ndarray]


def read_csv(path: str | Path) -> CsvRecording:
    """Read a gaitloop CSV file; every column must match the documented layout."""
    path = Path(path)
    try:
        table = pd.read_csv(path)
    except FileNotFoundError:
        raise IngestError(path, "file not found") from None
    except (ValueError, pd.errors.ParserError) as exc:
        raise IngestError(path, f"malformed CSV ({exc})") from None
    if "time_s" not in table.columns:
        raise IngestError(path, "no 'time_s' column")
    time = table["time_s"].to_numpy(float)
    if len(time) < 2 or not (np.diff(time) > 0).all():
        raise IngestError(path, "time_s must hold at least two strictly increasing samples")
    marker_cols: dict[str, dict[str, tuple[str, str]]] = {}
    angles: dict[str, np.ndarray] = {}
    for col in table.columns.drop("time_s"):
        if m := _MARKER.match(col):
            marker_cols.setdefault(m["name"], {})[m["axis"]] = (col, m["unit"])
        elif m := _ANGLE.match(col):
            values = table[col].to_numpy(float)
            angles[m["name"]] = np.degrees(values) if m["unit"] == "rad" else values
        else:
            raise IngestError(path, f"column {col!r} matches neither <marker>_<x|y|z>_<unit> "
                              "nor <angle>_<deg|rad>")
    names = tuple(sorted(marker_cols))
    xyz = np.full((len(time), len(names), 3), np.nan)
    for j, name in enumerate(names):
        axes = marker_cols[name]
        if set(axes) != {"x", "y", "z"}:
            raise IngestError(path, f"marker {name!r} lacks axes {sorted({'x', 'y', 'z'} - set(axes))}")
        for k, axis in enumerate("xyz"):
            col, unit = axes[axis]
            xyz[:, j, k] = table[col].to_numpy(float) * UNIT_TO_M[unit]
    rate = float((len(time) - 1) / (time[-1] - time[0]))
    unit = next(iter(marker_cols.values()))["x"][1] if marker_cols else "m"
    return CsvRecording(MarkerTable(path, rate, time, names, xyz, unit), angles)
