"""Strides: heel strike to the next ipsilateral heel strike, kept only when steady and straight.

Each stride gets one reason when rejected, checked in this order: ``events missing`` (too long,
or no toe off inside), ``mixed event sources (force, kinematic)`` (its two heel strikes come from
different event methods and no same-method pair times it: see below), ``marker gap`` (a heel,
toe or pelvis sample missing after gap filling),
``standing`` (pelvis slower than `min_speed_mps`), ``stepping in place`` (shorter than
`min_stride_length_m`), ``turn`` (heading change above `max_heading_change_deg`, or any turning
frame), ``start`` / ``stop`` (pelvis speed of the second step differing from the first by more than
`max_speed_change` of their mean,
or its speed outside `speed_tolerance` of the bout median; before or after the bout's middle),
``outside straight bout`` (overlaps frames where the subject stands still or turns).

A stride from a force-plate heel strike to a kinematic one (plates cover a few steps only) would mix
two event sources: the kinematic detector's bias against the plates (tens of ms; 35 ms on one lab's
data) would enter its time and every measure over it. Such a stride is timed from the kinematic
strikes at both ends instead (the one the plate event replaced, `ingest.events.merge_events`, within
`force_window_s`), so both ends carry the same bias; when there is none (no markers, or a plate event
with no kinematic match) it is rejected as ``mixed event sources (force, kinematic)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from pydantic import with_config

from ingest.bouts import Bout, PelvisPath
from ingest.events import times_by_side
from ingest.filtering import finite_frames
from ingest.spatiotemporal import stride_measures
from ingest.trial import SIDES


@with_config(extra="forbid")
@dataclass(frozen=True)
class StrideParams:

    max_stride_time_s: float = 2.0
    min_speed_mps: float = 0.3
    min_stride_length_m: float = 0.3
    max_heading_change_deg: float = 20.0
    max_speed_change: float = 0.15
    speed_tolerance: float = 0.15


STRIDE_COLUMNS = ["side", "stride", "t_start_s", "t_end_s", "kept", "reason", "stride_length_m",
                  "stride_time_s", "cadence_spm", "gait_speed_mps", "step_width_m"]


def _indices(time_s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Nearest frame of each time in `t`."""
    frames = np.interp(t, time_s, np.arange(len(time_s)))
    return np.clip(np.round(frames), 0, len(time_s) - 1).astype(int)


def _interp(time_s: np.ndarray, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Rows of the (n, k) signal `x` at the times `t`, linearly interpolated: (len(t), k)."""
    return np.column_stack([np.interp(t, time_s, x[:, k]) for k in range(x.shape[1])])


def segment_strides(events: pd.DataFrame, time_s: np.ndarray, heel: dict[str, np.ndarray],
                    toe: dict[str, np.ndarray], pelvis: np.ndarray, path: PelvisPath,
                    bouts: list[Bout], p: StrideParams, kinematic: pd.DataFrame | None = None,
                    window_s: float = 0.0) -> pd.DataFrame:
    """One row per stride of each side with its measures, `kept` flag and rejection reason;
    `kinematic` holds the kinematic events that time a stride whose heel strikes mix sources (module
    docstring), matched within `window_s`."""
    seen = finite_frames(pelvis)
    for m in (*heel.values(), *toe.values()):
        seen &= finite_frames(m)
    rows, bout = [], []
    times = times_by_side(events, [(s, e) for s in SIDES for e in ("heel_strike", "toe_off")])
    sources = _heel_strike_methods(events)
    kin_hs = ({s: times_by_side(kinematic, [(s, "heel_strike")])[s, "heel_strike"] for s in SIDES}
              if kinematic is not None else {s: np.empty(0) for s in SIDES})
    for side in SIDES:
        other = SIDES[1 - SIDES.index(side)]
        hs, to, contra = times[side, "heel_strike"], times[side, "toe_off"], times[other, "heel_strike"]
        frames, at_strike = _indices(time_s, hs), _interp(time_s, heel[side], hs)
        contra_at = _interp(time_s, heel[other], contra)
        first_contra = np.searchsorted(contra, hs, side="right")  # the first contralateral strike after each
        for k, (t0, t1) in enumerate(zip(hs[:-1], hs[1:], strict=True)):
            i0, i1, c = frames[k], frames[k + 1], first_contra[k]
            a0, a1, methods = at_strike[k], at_strike[k + 1], sources[side][k : k + 2]
            if len(set(methods)) > 1 and (same := _kinematic_pair(kin_hs[side], t0, t1, window_s)):
                t0, t1 = same
                i0, i1 = _indices(time_s, np.array(same))
                a0, a1 = _interp(time_s, heel[side], np.array(same))
                c, methods = int(np.searchsorted(contra, t0, side="right")), ["kinematic"] * 2
                c_at = _interp(time_s, heel[other], contra[c : c + 1]) if c < len(contra) else None
                contra_heel = c_at[0] if c < len(contra) and contra[c] < t1 else None
            else:
                contra_heel = contra_at[c] if c < len(contra) and contra[c] < t1 else None
            m = stride_measures(a0, a1, t0, t1, contra_heel)
            reason = _reject_reason(t0, t1, i0, i1, to, seen, pelvis, path, m.stride_length_m, p, methods)
            rows.append((side, k, t0, t1, reason is None, reason or "", m.stride_length_m,
                         m.stride_time_s, m.cadence_spm, m.gait_speed_mps, m.step_width_m))
            bout.append(_bout_of(bouts, i0, i1))
    if not rows:  # no stride: the measures' columns stay untyped, as an empty table always had them
        return pd.DataFrame([], columns=STRIDE_COLUMNS).astype(
            {"side": object, "stride": int, "kept": bool, "reason": object})
    side, stride, t_start, t_end, kept, reason, *measures = zip(*rows, strict=True)
    t_start, t_end = np.array(t_start, float), np.array(t_end, float)
    kept, reason = _reject_off_pace(np.array(kept, bool), np.array(reason, object), np.array(bout, int),
                                    np.array(measures[3], float), t_start, t_end, p)
    columns = [pd.Series(side, dtype=object), np.array(stride, np.int64), t_start, t_end, kept,
               pd.Series(reason, dtype=object), *(np.array(m, float) for m in measures)]
    return pd.DataFrame(dict(zip(STRIDE_COLUMNS, columns, strict=True)))


def _bout_of(bouts: list[Bout], i0: int, i1: int) -> int:
    for b, bout in enumerate(bouts):
        if bout.start <= i0 and i1 <= bout.stop:
            return b
    return -1


def _heel_strike_methods(events: pd.DataFrame) -> dict[str, list[str]]:
    """The `method` of each side's heel strikes, in the time order of `times_by_side`."""
    strikes = events[events["event"] == "heel_strike"].sort_values("time_s", kind="stable")
    return {side: strikes.loc[strikes["side"] == side, "method"].astype(str).tolist() for side in SIDES}


def _kinematic_pair(kin_hs: np.ndarray, t0: float, t1: float, window_s: float) -> tuple[float, float] | None:
    """The kinematic heel strikes nearest `t0` and `t1` when both lie within `window_s` of them."""
    if len(kin_hs) == 0:
        return None
    pair = []
    for t in (t0, t1):
        j = int(np.argmin(np.abs(kin_hs - t)))
        if abs(kin_hs[j] - t) > window_s:
            return None
        pair.append(float(kin_hs[j]))
    return (pair[0], pair[1]) if pair[0] < pair[1] else None


def _reject_reason(t0, t1, i0, i1, to, seen, pelvis, path, length, p, methods) -> str | None:
    """Why a stride is rejected (module docstring, in that order), None when kept; `seen` marks the
    frames where the pelvis, heels and toes were all seen, `methods` the event methods of its two
    heel strikes."""
    if t1 - t0 > p.max_stride_time_s or not ((to > t0) & (to < t1)).any():
        return "events missing"
    if len(set(methods)) > 1:
        return f"mixed event sources ({', '.join(sorted(set(methods)))})"
    window = slice(i0, i1 + 1)
    if not seen[window].all():
        return "marker gap"
    speed = path.speed_mps[window]
    if speed.mean() < p.min_speed_mps:
        return "standing"
    if length < p.min_stride_length_m:
        return "stepping in place"
    heading = path.heading_rad[window]
    if np.degrees(abs(heading[-1] - heading[0])) > p.max_heading_change_deg or path.turning[window].any():
        return "turn"
    v1, v2 = _half_stride_speeds(pelvis, i0, i1)
    if abs(v2 - v1) / ((v1 + v2) / 2) > p.max_speed_change:
        return "start" if v2 > v1 else "stop"
    return None


def _half_stride_speeds(pelvis: np.ndarray, i0: int, i1: int) -> tuple[float, float]:
    """Mean horizontal pelvis speed over each half of a stride (one step each), in m per frame:
    a ratio of the two shows acceleration without the edge effects of a smoothed velocity."""
    mid = (i0 + i1) // 2
    first = np.linalg.norm(pelvis[mid, :2] - pelvis[i0, :2]) / max(1, mid - i0)
    second = np.linalg.norm(pelvis[i1, :2] - pelvis[mid, :2]) / max(1, i1 - mid)
    return float(first), float(second)


def _reject_off_pace(kept: np.ndarray, reason: np.ndarray, bout: np.ndarray, speed: np.ndarray,
                     t_start: np.ndarray, t_end: np.ndarray,
                     p: StrideParams) -> tuple[np.ndarray, np.ndarray]:
    """(kept, reason) per stride after the bouts' pace check: within each straight bout, strides
    whose speed departs from the median of its steady strides are accelerating or decelerating,
    rejected as start (ending before the middle of the bout's kept strides) or stop; kept strides
    outside any bout are rejected as such."""
    kept, reason = kept.copy(), reason.copy()
    steady = kept & (bout >= 0)
    for b in np.unique(bout[steady]):
        group = steady & (bout == b)
        median = np.nanmedian(speed[group])
        middle = np.concatenate([t_start[group], t_end[group]]).mean()
        for j in np.flatnonzero(group & (np.abs(speed - median) > p.speed_tolerance * median)):
            kept[j], reason[j] = False, "start" if t_end[j] < middle else "stop"
    outside = kept & (bout < 0)
    reason[outside], kept[outside] = "outside straight bout", False
    return kept, reason


def kept_stride_runs(strides: pd.DataFrame, trial: str, margin_s: float, join_gap_s: float
                     ) -> list[tuple[float, float]]:
    """(start, end) times of the runs of kept strides of `trial` (strides overlapping or within
    `join_gap_s` of each other join one run), widened by `margin_s`: the steady straight walking
    of a recording, which the replay human walks."""
    kept = strides[(strides["trial"] == trial) & strides["kept"]].sort_values("t_start_s")
    runs: list[list[float]] = []
    for t0, t1 in zip(kept["t_start_s"], kept["t_end_s"], strict=True):
        if runs and t0 <= runs[-1][1] + join_gap_s:
            runs[-1][1] = max(runs[-1][1], t1)
        else:
            runs.append([t0, t1])
    return [(r0 - margin_s, r1 + margin_s) for r0, r1 in runs]
