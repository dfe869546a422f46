"""The canonical Trial every reader produces and every processing step consumes.

Frame (DESIGN.md): Z up, X along the direction of progression, Y to the left; metres, seconds,
degrees. Signs: hip flexion +, knee flexion +, ankle dorsiflexion +, pelvis anterior tilt +.
Marker positions stay in the laboratory frame rotated to Z up; the progression direction of each
straight bout is found by `ingest.bouts` because a trial may contain turns.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ingest.errors import IngestError
from ingest.readers.robot_log import RobotLog
from ingest.subject import RobotMarkers

JOINTS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
SIDES = ("left", "right")


@dataclass(frozen=True)
class Provenance:
    """Where a trial came from: file path, its sha256 and the reader that parsed it; `key`: the file's
    manifest key (data/sources.yaml), the same on every machine, where it has one."""

    file: str
    sha256: str
    reader: str
    key: str = ""


@dataclass(frozen=True)
class ForcePlates:
    """Per-plate ground reaction: vertical force (N) and centre of pressure (m, canonical frame).

    Arrays are (n_frames, n_plates) for `fz_n` and (n_frames, n_plates, 3) for `cop_m`, sampled at
    `rate_hz` starting at `t0_s`.
    """

    rate_hz: float
    t0_s: float
    fz_n: np.ndarray
    cop_m: np.ndarray

    @property
    def time_s(self) -> np.ndarray:
        return self.t0_s + np.arange(self.fz_n.shape[0]) / self.rate_hz


@dataclass(frozen=True)
class Trial:
    """One recording in the canonical frame.

    `markers` maps marker name to an (n, 3) array in metres (NaN where missing); `angles` maps
    canonical joint angle names (e.g. ``knee_flexion_l``, ``pelvis_tilt``) to (n,) arrays in
    degrees. Both are sampled at `rate_hz` on `time_s`.
    """

    subject: str
    condition: str
    source: str
    trial: str
    rate_hz: float
    time_s: np.ndarray
    markers: dict[str, np.ndarray] = field(default_factory=dict)
    angles: dict[str, np.ndarray] = field(default_factory=dict)
    plates: ForcePlates | None = None
    provenance: tuple[Provenance, ...] = ()
    robot_log: RobotLog | None = None  # the robot's own log of a robot-assisted trial
    robot_markers: RobotMarkers | None = None  # or markers on the robot that give it (ingest.robot_log)
    # the time column of each file read, by kind (markers, angles, grf), as the file gives it: whether
    # the files cover each other is a quality gate (metrics.quality.ingest_checks)
    file_time_s: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(self.time_s)

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if self.n_frames else 0.0

    @property
    def origin(self) -> str:
        """The file(s) this trial came from, for error messages."""
        return ", ".join(p.file for p in self.provenance) or f"{self.subject}/{self.trial}"

    def with_(self, **changes: object) -> Trial:
        return replace(self, **changes)

    def marker(self, name: str) -> np.ndarray:
        try:
            return self.markers[name]
        except KeyError:
            raise IngestError(
                self.origin, f"marker {name!r} is missing (has: {', '.join(sorted(self.markers))})"
            ) from None
