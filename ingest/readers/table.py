"""What every marker reader returns: `MarkerTable` (markers in the file's lab axes, metres), and the
length units a marker file may declare (`UNIT_TO_M`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

UNIT_TO_M = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}


@dataclass(frozen=True)
class MarkerTable:
    """Markers as read: lab axes of the file, converted to metres from the declared unit."""

    path: Path
    rate_hz: float
    time_s: np.ndarray
    names: tuple[str, ...]
    xyz_m: np.ndarray  # (n_frames, n_markers, 3)
    declared_unit: str
