"""Spatiotemporal parameters of one stride (heel strike to the next ipsilateral heel strike).

- stride length: horizontal distance between the heel positions at the two heel strikes;
- stride time, cadence (steps/min = 2 * 60 / stride time), gait speed (length / time);
- step width: distance of the contralateral heel at its heel strike inside the stride from the
  line joining the two ipsilateral heel-strike positions (the usual definition, e.g. Perry &
  Burnfield 2010, *Gait Analysis*, ch. 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StrideMeasures:
    stride_length_m: float
    stride_time_s: float
    cadence_spm: float
    gait_speed_mps: float
    step_width_m: float


def stride_measures(heel_start: np.ndarray, heel_end: np.ndarray, t_start_s: float,
                    t_end_s: float, contra_heel: np.ndarray | None) -> StrideMeasures:
    """Measures from the ipsilateral heel at both strikes and the contralateral heel at its
    strike (positions in metres, canonical frame; NaN where a marker is missing)."""
    d = heel_end[:2] - heel_start[:2]
    length = float(np.hypot(*d))
    time = t_end_s - t_start_s
    width = np.nan
    if contra_heel is not None and length > 0:
        rel = contra_heel[:2] - heel_start[:2]
        width = float(abs(d[0] * rel[1] - d[1] * rel[0]) / length)
    return StrideMeasures(length, time, 120.0 / time, length / time, width)
