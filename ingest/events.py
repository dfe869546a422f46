"""Gait events (heel strike, toe off) per side, from force plates or from kinematics.

- Force plates: a contact starts when the vertical ground reaction rises above
  `force_threshold_n` (20 N, as in Zeni et al. 2008) and ends when it falls below it; contacts
  shorter than `min_contact_s` are ignored, and contacts running into the start or end of the
  recording give no event there. Each contact is assigned to the foot whose heel-toe midpoint is
  nearest the centre of pressure. A foot that steps from one plate onto another keeps one contact.
- Kinematics (Zeni, Richards & Higginson 2008, Gait Posture 27:710): toe off at the peak
  posterior position of the toe relative to the pelvis centre along the direction of progression;
  heel strike near the peak anterior position of the heel, refined to the moment the descending
  heel settles (its vertical velocity rises above -`heel_settle_mps` within `settle_window_s`
  after the peak). The refinement removes the 40-50 ms early bias of the bare Zeni peak that we
  measured against force plates on both example subjects (the heel is still descending at its
  most anterior point).
- A recording that starts with a heel already at its most anterior point (a peak cut by the start)
  gets a heel strike there only when the foot is landing at that moment: heel within
  `start_heel_height_m` of its stance level (5th percentile of its height over the trial), heel
  vertical speed below `start_heel_speed_mps`, and the toe still coming down faster than
  `start_toe_descent_mps` (the foot is not yet flat). A foot in swing, a foot already flat
  (mid-stance, or quiet standing) and a trailing heel rising towards toe off get none: the strike
  happened before the recording. Thresholds from the filtered markers at the plate-measured heel
  strikes of both example subjects: heel -9..+17 mm above its stance level and -0.37..+0.24 m/s,
  toe descending at 0.55-1.5 m/s (flat within ~0.1 s); a rising trailing heel stands 48-92 mm
  above its stance level at 0.6-1.2 m/s.
- `auto`: kinematic events everywhere, replaced by the force-plate event of the same side and
  kind when one lies within `force_window_s` (plates usually cover a few steps only).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd
import scipy  # scipy.signal loads on first use (see ingest/filtering.py)
from pydantic import with_config

from ingest.errors import IngestError
from ingest.filtering import finite_runs
from ingest.trial import SIDES, ForcePlates

EVENT_COLUMNS = ["side", "event", "time_s", "method"]


@with_config(extra="forbid")
@dataclass(frozen=True)
class EventParams:

    method: Literal["auto", "force", "kinematic"] = "auto"
    force_threshold_n: float = 20.0
    min_contact_s: float = 0.2
    force_window_s: float = 0.1
    min_event_interval_s: float = 0.5
    min_prominence_m: float = 0.1
    heel_settle_mps: float = 0.05
    settle_window_s: float = 0.25
    start_heel_height_m: float = 0.03
    start_heel_speed_mps: float = 0.4
    start_toe_descent_mps: float = 0.2


def _frame(rows: list[tuple[str, str, float, str]]) -> pd.DataFrame:
    """The events table of `rows`, by time, then side (stable: ties keep their order); sorted as
    rows, which costs a fraction of sorting the table (event times are finite)."""
    return pd.DataFrame(sorted(rows, key=lambda row: (row[2], row[0])), columns=EVENT_COLUMNS)


def force_plate_events(plates: ForcePlates, feet_xy: dict[str, np.ndarray], time_s: np.ndarray,
                       p: EventParams) -> pd.DataFrame:
    """Heel strikes and toe offs from plate contacts; `feet_xy[side]` is the (n, 2) heel-toe
    midpoint of each foot sampled on `time_s` (used to tell which foot loaded the plate)."""
    t_plate = plates.time_s
    n = len(t_plate)
    contact = {side: np.zeros(n, bool) for side in SIDES}
    min_len = int(round(p.min_contact_s * plates.rate_hz))
    for k in range(plates.fz_n.shape[1]):
        loaded = plates.fz_n[:, k] > p.force_threshold_n
        for start, stop in finite_runs(loaded):
            if stop - start < min_len:
                continue
            window = slice(start, min(stop, start + max(2, min_len // 2)))
            cop = np.nanmean(plates.cop_m[window, k, :2], axis=0)
            t_mid = t_plate[window].mean()
            dist = {side: np.linalg.norm(_at(time_s, feet_xy[side], t_mid) - cop) for side in SIDES}
            side = min(dist, key=dist.get)
            if np.isfinite(dist[side]):
                contact[side][start:stop] = True
    rows = []
    for side in SIDES:
        for start, stop in finite_runs(contact[side]):
            if start > 0:
                rows.append((side, "heel_strike", float(t_plate[start]), "force"))
            if stop < n:
                rows.append((side, "toe_off", float(t_plate[stop]), "force"))
    return _frame(rows)


def side_times(events: pd.DataFrame, side: str, event: str) -> np.ndarray:
    """Sorted times of one side's events of one kind."""
    return times_by_side(events, [(side, event)])[side, event]


def times_by_side(events: pd.DataFrame, keys: Iterable[tuple[str, str]]) -> dict[tuple[str, str], np.ndarray]:
    """`side_times` of each (side, event) of `keys`, the table's columns converted once."""
    sides, kinds = events["side"].to_numpy(), events["event"].to_numpy()
    times = events["time_s"].to_numpy(float)
    return {(side, event): np.sort(times[(sides == side) & (kinds == event)]) for side, event in keys}


def _at(time_s: np.ndarray, xy: np.ndarray, t: float) -> np.ndarray:
    i = int(np.clip(np.searchsorted(time_s, t), 0, len(time_s) - 1))
    return xy[i]


def _refined_peak(x: np.ndarray, i: int) -> float:
    """Sub-sample peak position by a parabola through the peak and its neighbours."""
    if 0 < i < len(x) - 1:
        denom = x[i - 1] - 2 * x[i] + x[i + 1]
        if denom != 0 and np.isfinite(denom):
            return i + 0.5 * (x[i - 1] - x[i + 1]) / denom
    return float(i)


def _heel_settled(z: np.ndarray, i: int, rate_hz: float, p: EventParams) -> float | None:
    """Fractional frame after `i` where the heel's vertical velocity first exceeds
    -heel_settle_mps, or None when it does not within the window."""
    stop = min(len(z) - 1, i + int(p.settle_window_s * rate_hz))
    if stop - i < 2:
        return None
    vz = np.diff(z[i : stop + 1]) * rate_hz  # velocity at the half-frames i + 0.5, i + 1.5, ...
    above = np.flatnonzero(vz > -p.heel_settle_mps)
    if len(above) == 0 or not np.isfinite(vz).all():
        return None
    j = above[0]
    if j == 0:
        return i + 0.5
    frac = (-p.heel_settle_mps - vz[j - 1]) / (vz[j] - vz[j - 1])
    return i + j - 0.5 + frac


def _peak_at_start(x: np.ndarray, distance: int, prominence: float) -> bool:
    """A maximum cut by the start of the recording: the signal falls from its first sample by
    at least `prominence` before rising again (the heel was already at its most anterior point)."""
    head = x[: distance + 1]
    if len(head) < 3 or not x[0] >= x[1]:
        return False
    trough = int(np.argmin(head))
    return bool(x[0] - head[trough] >= prominence and (x[1 : trough + 1] <= x[0]).all())


def _landing(heel_z: np.ndarray, toe_z: np.ndarray, k: int, rate_hz: float, p: EventParams) -> bool:
    """Whether frame `k` is a heel landing (module docstring): heel loaded near its stance level and
    nearly still, toe still descending (the foot not yet flat)."""
    if not 0 <= k < len(heel_z) or len(heel_z) < 3:
        return False
    window = slice(max(0, k - 1), min(len(heel_z), k + 2))
    if not (np.isfinite(heel_z[window]).all() and np.isfinite(toe_z[window]).all()):
        return False
    with np.errstate(all="ignore"):
        stance_level = np.nanpercentile(heel_z, 5)
    heel_v = np.gradient(heel_z[window]) * rate_hz
    toe_v = np.gradient(toe_z[window]) * rate_hz
    j = k - window.start
    return bool(heel_z[k] - stance_level <= p.start_heel_height_m
                and abs(heel_v[j]) <= p.start_heel_speed_mps
                and toe_v[j] < -p.start_toe_descent_mps)


def kinematic_events(heel: dict[str, np.ndarray], toe: dict[str, np.ndarray], pelvis: np.ndarray,
                     heading_rad: np.ndarray, time_s: np.ndarray, rate_hz: float,
                     p: EventParams) -> pd.DataFrame:
    """Zeni et al. (2008) events from heel, toe and pelvis-centre positions (canonical frame)."""
    direction = np.column_stack([np.cos(heading_rad), np.sin(heading_rad)])
    distance = max(1, int(p.min_event_interval_s * rate_hz))
    found = []  # (side, event, fractional frame)
    for side in SIDES:
        for marker, sign, event in ((heel[side], 1.0, "heel_strike"), (toe[side], -1.0, "toe_off")):
            rel = np.einsum("ij,ij->i", marker[:, :2] - pelvis[:, :2], direction) * sign
            filled = np.where(np.isfinite(rel), rel, np.nanmin(rel) if np.isfinite(rel).any() else 0)
            peaks, _ = scipy.signal.find_peaks(filled, distance=distance, prominence=p.min_prominence_m / 2)
            if event == "heel_strike" and _peak_at_start(filled, distance, p.min_prominence_m / 2):
                peaks = np.concatenate(([0], peaks))
            for i in peaks:
                if not np.isfinite(rel[max(0, i - 1) : i + 2]).all():
                    continue
                at = _refined_peak(rel, i)
                if event == "heel_strike":
                    settled = _heel_settled(marker[:, 2], i, rate_hz, p)
                    if i == 0 and (settled is None or not _landing(
                            marker[:, 2], toe[side][:, 2], int(round(settled)), rate_hz, p)):
                        continue  # a cut peak: the foot is not landing in the recording
                    at = settled or at
                found.append((side, event, at))
    times = np.interp([at for _, _, at in found], np.arange(len(time_s)), time_s)
    return _frame([(side, event, float(t), "kinematic")
                   for (side, event, _), t in zip(found, times, strict=True)])


def merge_events(kinematic: pd.DataFrame, force: pd.DataFrame, window_s: float) -> pd.DataFrame:
    """Kinematic events with those matched by a force-plate event (same side and kind, within
    `window_s`) replaced by it; unmatched plate events are added."""
    times = kinematic["time_s"].to_numpy(float).copy()
    methods = kinematic["method"].to_numpy(object).copy()
    sides, kinds = kinematic["side"].to_numpy(object), kinematic["event"].to_numpy(object)
    extra = []
    columns = (force[c].to_numpy().tolist() for c in EVENT_COLUMNS)  # cheaper than iterating rows
    for side, event, t, method in zip(*columns, strict=True):
        candidates = np.flatnonzero((sides == side) & (kinds == event))
        if len(candidates):
            j = candidates[np.argmin(np.abs(times[candidates] - t))]
            if abs(times[j] - t) <= window_s:
                times[j], methods[j] = t, method
                continue
        extra.append((side, event, t, method))
    rows = list(zip(sides, kinds, times, methods, strict=True))
    return _frame(rows + extra)


def detect_events(method: str, *, plates: ForcePlates | None, kin: pd.DataFrame | None,
                  force: pd.DataFrame | None, window_s: float, origin: str) -> pd.DataFrame:
    """Pick or combine the event sources by `method` (auto | force | kinematic)."""
    if method == "force":
        if plates is None or force is None:
            raise IngestError(origin, "events method 'force' but the trial has no force plates")
        return force
    if method == "kinematic":
        if kin is None:
            raise IngestError(origin, "events method 'kinematic' needs heel, toe and pelvis markers")
        return kin
    if method != "auto":
        raise IngestError(origin, f"unknown events method {method!r} (auto | force | kinematic)")
    if kin is None and force is None:
        raise IngestError(origin, "no markers and no force plates: cannot detect gait events")
    if kin is None:
        return force
    return kin if force is None else merge_events(kin, force, window_s)


@dataclass(frozen=True)
class EventScore:
    """Agreement of detected events with reference (force-plate) events of one kind."""

    n_truth: int
    n_matched: int
    median_abs_error_s: float
    mean_error_s: float

    @property
    def matched_fraction(self) -> float:
        return self.n_matched / self.n_truth if self.n_truth else float("nan")


def score_events(detected: pd.DataFrame, truth: pd.DataFrame, event: str = "heel_strike",
                 window_s: float = 0.1) -> EventScore:
    """Match each reference event to the nearest detected one of the same side and kind."""
    errors = []
    n_truth = 0
    for side in SIDES:
        ref, det = (side_times(df, side, event) for df in (truth, detected))
        n_truth += len(ref)
        for t in ref:
            if len(det):
                dt = det[np.argmin(np.abs(det - t))] - t
                if abs(dt) <= window_s:
                    errors.append(dt)
    errors_arr = np.array(errors)
    return EventScore(
        n_truth, len(errors),
        float(np.median(np.abs(errors_arr))) if len(errors) else float("nan"),
        float(errors_arr.mean()) if len(errors) else float("nan"),
    )
