"""Compliance and harness force per scenario phase (standing, start, steady, speed change, turn, stop),
and their time course around the commanded events.

Follow-me controllers differ when the person starts, stops, changes speed or turns; a whole-walk
mean hides that. Each simulated run (trial, seed) gives its mean |e_x|, |e_y| (cm) and its harness
force RMS (N) over the following samples of one phase; the table reports the mean over runs with a
95 % confidence interval across seeds (Student t, runs as the independent samples), so two
controllers are told apart only beyond seed noise.

`event_traces` shows what happens at a transition: each run's e_x, e_y (cm, signed) and harness
force |f| (N) on a time grid around the onset of a commanded phase (start, turn, stop: the first
sample of that phase in the run), averaged across runs with the same 95 % CI.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (~0.6 s): stages without intervals skip it
from pydantic import Field, with_config

from metrics.compliance import FORCE, following, run_means
from metrics.groups import GROUP, with_identity
from metrics.table import GROUP_COLUMNS, MetricTable

KEYS = [*GROUP, "scenario", "phase"]
QUANTITIES = {"abs_ex_cm": "mean |e_x| (cm)", "abs_ey_cm": "mean |e_y| (cm)",
              "force_rms_n": "harness |f| RMS (N)"}
SCHEMA = {**GROUP_COLUMNS, "scenario": "VARCHAR", "phase": "VARCHAR", "n_runs": "BIGINT",
          "n_samples": "BIGINT", "falls": "BIGINT",
          **{f"{q}_{s}": "DOUBLE" for q in QUANTITIES for s in ("mean", "ci95")}}
COLUMNS = list(SCHEMA)

EVENT_KEYS = [*GROUP, "scenario", "event", "t_s"]
EVENT_QUANTITIES = {"ex_cm": "e_x (cm)", "ey_cm": "e_y (cm)", "force_n": "harness |f| (N)"}
EVENT_SCHEMA = {**GROUP_COLUMNS, "scenario": "VARCHAR", "event": "VARCHAR", "t_s": "DOUBLE",
                "n_runs": "BIGINT",
                **{f"{q}_{s}": "DOUBLE" for q in EVENT_QUANTITIES for s in ("mean", "ci95")}}
EVENT_COLUMNS = list(EVENT_SCHEMA)


@with_config(extra="forbid")
@dataclass(frozen=True)
class EventWindow:
    """`metrics.events` of params.yaml: the commanded phases whose onsets are events, and the time
    window around each onset (s, grid step `step_s`). The defaults cover the gait initiation
    (about 1.7 s, `scenarios.profile.start_s`), a 90 deg turn (1 s at 90 deg/s) and the stop
    (1.4 s) with a second before the command."""

    names: tuple[str, ...] = ("start", "turn", "stop")
    window_s: tuple[float, float] = (-1.0, 3.0)
    step_s: Annotated[float, Field(gt=0.0)] = 0.05

    def __post_init__(self) -> None:
        if not self.window_s[0] < 0.0 < self.window_s[1]:
            raise ValueError(f"window_s: must run from before to after the event (got {list(self.window_s)})")

    def grid(self) -> np.ndarray:
        """Times relative to the onset (s), both window ends included."""
        n = int(round((self.window_s[1] - self.window_s[0]) / self.step_s))
        return self.window_s[0] + self.step_s * np.arange(n + 1)


def run_values(robot: pd.DataFrame, exclude_locked: bool = True) -> pd.DataFrame:
    """One row per run and phase: its mean |e_x|, |e_y| (cm), harness force RMS (N), samples, fall."""
    robot = with_identity(robot, "robot table", ("scenario", "phase", "trial", "e_x_m", "e_y_m", *FORCE,
                                                 "fall"))
    rows = []
    for key, g in robot.groupby([*KEYS, "trial", "seed"], sort=True):
        f = following(g, exclude_locked)
        rows.append((*key, len(f), bool(g["fall"].any()), *run_means(f)))
    return pd.DataFrame(rows, columns=[*KEYS, "trial", "seed", "n_samples", "fell", *QUANTITIES])


def mean_ci95(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and half-width of the 95 % Student-t confidence interval along the first axis, over the
    finite values: mean NaN without any, half-width NaN with fewer than 2. A 1-D `x` gives 0-d
    arrays (use `float()`)."""
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(ok, x, 0.0).sum(axis=0) / n
        sd = np.sqrt(np.where(ok, (x - mean) ** 2, 0.0).sum(axis=0) / (n - 1))
        half = np.where(n >= 2, scipy.stats.t.ppf(0.975, np.maximum(n - 1, 1)) * sd / np.sqrt(n), np.nan)
    return np.asarray(mean), half


def phase_table(robot: pd.DataFrame, exclude_locked: bool = True) -> pd.DataFrame:
    """Per group, scenario and phase: runs, samples, falls, and mean with 95 % CI over runs of
    |e_x|, |e_y| and harness force RMS (module docstring). Empty robot table -> empty table."""
    if robot.empty:
        return pd.DataFrame(columns=COLUMNS)
    runs = run_values(robot, exclude_locked)
    rows = []
    for key, g in runs.groupby(KEYS, sort=True):
        values = [float(v) for q in QUANTITIES for v in mean_ci95(g[q].to_numpy(float))]
        rows.append((*key, len(g), int(g["n_samples"].sum()), int(g["fell"].sum()), *values))
    return pd.DataFrame(rows, columns=COLUMNS)


def run_event_traces(run: pd.DataFrame, w: EventWindow, exclude_locked: bool = True
                     ) -> dict[str, np.ndarray]:
    """One run's traces around each event of `w` it contains: event -> (len(grid), 3) array of e_x
    (cm), e_y (cm), |f| (N), linearly interpolated at onset + grid. Samples after an arm lock
    (`exclude_locked`) and times outside the run are NaN. A run that begins in the event's phase
    has no onset and gives no trace."""
    run = run.sort_values("time_s")
    t = run["time_s"].to_numpy(float)
    values = np.column_stack([run["e_x_m"].to_numpy(float) * 100, run["e_y_m"].to_numpy(float) * 100,
                              np.linalg.norm(run[FORCE].to_numpy(float), axis=1)])
    if exclude_locked:
        values[run["locked"].to_numpy(bool)] = np.nan
    phase = run["phase"].to_numpy(str)
    out = {}
    for event in w.names:
        onset = np.flatnonzero(phase == event)
        if len(onset) and onset[0] > 0:
            at = t[onset[0]] + w.grid()
            out[event] = np.column_stack([np.interp(at, t, v, left=np.nan, right=np.nan) for v in values.T])
    return out


def event_traces(robot: pd.DataFrame, w: EventWindow = EventWindow(), exclude_locked: bool = True
                 ) -> pd.DataFrame:
    """Per group, scenario, event and time from the onset (`t_s`): runs with a value there, and
    mean with 95 % CI across runs of e_x, e_y (cm) and harness |f| (N) (module docstring).
    Empty robot table -> empty table."""
    if robot.empty:
        return pd.DataFrame(columns=EVENT_COLUMNS)
    robot = with_identity(robot, "robot table", ("scenario", "phase", "trial", "time_s", "e_x_m", "e_y_m",
                                                 *FORCE, "locked"))
    traces: dict[tuple, list[np.ndarray]] = {}
    for key, run in robot.groupby([*GROUP, "scenario", "trial", "seed"], sort=True):
        for event, trace in run_event_traces(run, w, exclude_locked).items():
            traces.setdefault((*key[:len(GROUP) + 1], event), []).append(trace)
    frames = []
    for key, runs in sorted(traces.items()):
        mean, half = mean_ci95(np.stack(runs))  # (time, quantity) each
        frame = pd.DataFrame({"t_s": w.grid(), "n_runs": np.isfinite(np.stack(runs)[:, :, 0]).sum(axis=0)})
        for k, q in enumerate(EVENT_QUANTITIES):
            frame[f"{q}_mean"], frame[f"{q}_ci95"] = mean[:, k], half[:, k]
        for col, value in zip([*GROUP, "scenario", "event"], key, strict=True):
            frame[col] = value
        frames.append(frame[EVENT_COLUMNS])
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=EVENT_COLUMNS)


TABLE = MetricTable("phases", SCHEMA, lambda inputs, p: phase_table(inputs.scenario_robot, p.exclude_locked),
                    title="Compliance and harness force per scenario phase (mean ± 95 % CI across runs; "
                          "falls count the runs that had fallen by the end of the phase)")
EVENT_TABLE = MetricTable("event_traces", EVENT_SCHEMA,
                          lambda inputs, p: event_traces(inputs.scenario_robot, p.events, p.exclude_locked))

__all__ = ["COLUMNS", "EVENT_COLUMNS", "EVENT_QUANTITIES", "EVENT_TABLE", "KEYS", "QUANTITIES", "TABLE",
           "EventWindow", "event_traces", "mean_ci95", "phase_table", "run_event_traces", "run_values"]
