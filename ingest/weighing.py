"""The subject's mass as the force plates weigh it, checked against the mass the subject file types.

Over one stride (a force-plate heel strike to the next of the same foot) the body ends where it began
vertically, so the vertical impulse is body weight times the stride time: the mean total vertical
force over the stride, divided by g, is the mass. Only strides in which the total force never drops
below the contact threshold count: every foot contact of the stride was on a plate (walking has no
flight phase). On the bundled subjects this weighs within 8 % of the stated masses (camargo 77.9 kg
for 74.8, opencap4 59.8 for 62.6, kgc6 65.1 for 70, lenhart2015 66.8 for 62); a mass typed in
pounds is 2.2 times off.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import SubjectError
from ingest.events import side_times
from ingest.trial import SIDES, ForcePlates

G_MPS2 = 9.80665
MASS_TOLERANCE = 0.10  # typed mass vs plates' weighing, relative to the weighing
MAX_STRIDE_S = 2.5     # consecutive heel strikes further apart are not one stride


def stride_masses(plates: ForcePlates, events: pd.DataFrame, threshold_n: float) -> list[float]:
    """Mass (kg) weighed over each stride of `events` (force-plate heel strikes, `method` force) whose
    every frame the plates load above `threshold_n` in total; [] when none is wholly on plates."""
    total = np.nansum(plates.fz_n, axis=1)
    t = plates.time_s
    force = events[events["method"] == "force"]
    masses = []
    for side in SIDES:
        strikes = side_times(force, side, "heel_strike")
        for a, b in zip(strikes[:-1], strikes[1:], strict=True):
            inside = (t >= a) & (t < b)
            if b - a <= MAX_STRIDE_S and inside.sum() > 1 and (total[inside] > threshold_n).all():
                masses.append(float(total[inside].mean() / G_MPS2))
    return masses


def check_mass(mass_kg: float, masses: list[float], source: str | Path) -> None:
    """`SubjectError` naming `source` when the typed `mass_kg` is more than `MASS_TOLERANCE` from the
    median of the plates' stride `masses` (nothing to check without them)."""
    if not masses:
        return
    weighed = float(np.median(masses))
    if abs(mass_kg - weighed) > MASS_TOLERANCE * weighed:
        raise SubjectError(source, f"mass_kg {mass_kg:g} but the force plates weigh the subject at "
                                   f"{weighed:.1f} kg (median of {len(masses)} strides wholly on plates), "
                                   f"{abs(mass_kg / weighed - 1):.0%} apart (more than "
                                   f"{MASS_TOLERANCE:.0%}): is the mass in kilograms (pounds / 2.205)?")


__all__ = ["G_MPS2", "MASS_TOLERANCE", "check_mass", "stride_masses"]
