"""Left-right symmetry and stride-to-stride variability of a walk, for the virtual cohort.

Per side, over the kept strides: stance time (heel strike to that foot's next toe-off) and swing
time (stride time minus stance). Ratios are left over right, so a value above 1 leans left; the
clinical symmetry ratio is the larger over the smaller (Patterson et al. 2010, Gait Posture
31:241, whose healthy 95 % upper bounds are 1.05 for stance and 1.06 for swing time). Stride-time
variability is the coefficient of variation of the kept strides' times (healthy young adults about
1.3 %: Hausdorff et al. 1999, J Appl Physiol 86:1040; data/paper/clinical_ranges.yaml).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

SYMMETRY_COLUMNS = ["stance_l_s", "stance_r_s", "swing_l_s", "swing_r_s", "stance_ratio_lr", "swing_ratio_lr",
                    "stride_time_cv_pct"]


def symmetry_row(strides: pd.DataFrame, events: pd.DataFrame) -> dict:
    """`SYMMETRY_COLUMNS` of one walk from its strides and events tables (NaN where a side has no
    kept stride with a toe-off inside it)."""
    out = dict.fromkeys(SYMMETRY_COLUMNS, np.nan)
    if strides.empty or events.empty:
        return out
    kept = strides[strides["kept"].astype(bool)]
    if len(kept) >= 2:
        st = kept["stride_time_s"].to_numpy(float)
        out["stride_time_cv_pct"] = float(100.0 * st.std(ddof=1) / st.mean())
    toe = events[events["event"] == "toe_off"]
    for side, name in (("l", "left"), ("r", "right")):
        offs = np.sort(toe.loc[toe["side"] == name, "time_s"].to_numpy(float))
        stance, swing = [], []
        for a, b in kept.loc[kept["side"] == name, ["t_start_s", "t_end_s"]].to_numpy(float):
            k = np.searchsorted(offs, a, side="right")
            if k < len(offs) and offs[k] < b:
                stance.append(offs[k] - a)
                swing.append(b - offs[k])
        if stance:
            out[f"stance_{side}_s"], out[f"swing_{side}_s"] = float(np.mean(stance)), float(np.mean(swing))
    out["stance_ratio_lr"] = out["stance_l_s"] / out["stance_r_s"]
    out["swing_ratio_lr"] = out["swing_l_s"] / out["swing_r_s"]
    return out
