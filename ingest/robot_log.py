"""The robot table of a real robot-assisted trial, from the robot's log (`ingest.readers.robot_log`).

The log has its own clock rate; the metrics want one row per mocap sample, like the simulation
writes. So the log is resampled onto the mocap times: linear interpolation for signals (the yaw
unwrapped first, so a turn through +-pi does not swing back), previous-sample hold for the fall and
locked flags. Base speed (along the heading) and yaw rate are differentiated on the log's own time
before resampling. Where the log's samples are the mocap's (same count, times within 1e-9 s), the
values are copied, not interpolated.

Without a log, markers on the robot give the same signals (`log_from_markers`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import IngestError
from ingest.gaps import fill_short
from ingest.readers.robot_log import RobotLog
from ingest.robot import ROBOT_COLUMNS
from ingest.subject import RobotMarkers

SAME_TIME_TOL_S = 1e-9


def _check_coverage(log: RobotLog, time_s: np.ndarray) -> None:
    """The log must cover the mocap's span, to within half a log sample at either end."""
    half = 0.5 * float(np.median(np.diff(log.time_s)))
    t0, t1 = float(log.time_s[0]), float(log.time_s[-1])
    if t0 > time_s[0] + half or t1 < time_s[-1] - half:
        raise IngestError(log.path, f"robot log covers {t0:.3f}..{t1:.3f} s, the mocap trial "
                                    f"{time_s[0]:.3f}..{time_s[-1]:.3f} s")


def robot_table(log: RobotLog, time_s: np.ndarray, subject: str, condition: str, trial: str) -> pd.DataFrame:
    """The robot table (`ingest.robot.ROBOT_COLUMNS`, source "real") with one row per mocap time.

    `pelvis_x_m`/`pelvis_y_m` are NaN (a real robot measures only its arm); commands and the harness
    wrench are NaN when the log lacks them, the flags False. `base_yaw_rad` is the unwrapped yaw.
    """
    time_s = np.asarray(time_s, dtype=float)
    if time_s.ndim != 1 or len(time_s) == 0 or not np.isfinite(time_s).all():
        raise IngestError(log.path, f"mocap times must be a non-empty finite 1-D array, got shape "
                                    f"{time_s.shape}")
    _check_coverage(log, time_s)
    t = log.time_s
    yaw = np.unwrap(log.base_yaw_rad)
    velocity = np.gradient(log.base_xy_m, t, axis=0)
    speed = velocity[:, 0] * np.cos(yaw) + velocity[:, 1] * np.sin(yaw)
    n = len(t)
    signals = np.column_stack([
        log.arm_m, log.base_xy_m, yaw, speed, np.gradient(yaw, t),
        log.cmd if log.cmd is not None else np.full((n, 2), np.nan),
        log.wrench if log.wrench is not None else np.full((n, 6), np.nan),
    ])
    flags = np.column_stack([f if f is not None else np.zeros(n, bool) for f in (log.fall, log.locked)])
    if len(t) == len(time_s) and np.max(np.abs(t - time_s)) <= SAME_TIME_TOL_S:
        values, held = signals.copy(), flags.copy()
    else:
        values = np.column_stack([np.interp(time_s, t, column) for column in signals.T])
        held = flags[np.clip(np.searchsorted(t, time_s, side="right") - 1, 0, n - 1)]
    nan = np.full(len(time_s), np.nan)
    table = pd.DataFrame({
        "subject": subject, "source": "real", "human_mode": "none", "condition": condition,
        "trial": trial, "seed": np.zeros(len(time_s), dtype=np.int64), "time_s": time_s,
        "e_x_m": values[:, 0], "e_y_m": values[:, 1], "e_z_m": values[:, 2],
        "pelvis_x_m": nan, "pelvis_y_m": nan.copy(),
        "base_x_m": values[:, 3], "base_y_m": values[:, 4], "base_yaw_rad": values[:, 5],
        "base_speed_mps": values[:, 6], "base_yaw_rate_rps": values[:, 7],
        "cmd_speed_mps": values[:, 8], "cmd_yaw_rate_rps": values[:, 9],
        "harness_fx_n": values[:, 10], "harness_fy_n": values[:, 11], "harness_fz_n": values[:, 12],
        "harness_tx_nm": values[:, 13], "harness_ty_nm": values[:, 14], "harness_tz_nm": values[:, 15],
        "fall": held[:, 0].astype(bool), "locked": held[:, 1].astype(bool),
    })
    return table[ROBOT_COLUMNS]


__all__ = ["SAME_TIME_TOL_S", "robot_table"]


def log_from_table(table: pd.DataFrame, path: Path) -> RobotLog:
    """The robot log of one run's robot table (`ingest.robot.ROBOT_COLUMNS`), the inverse of
    `robot_table`: what a robot would have logged (arm, odometry, commands, the harness wrench as a
    load cell measures it, flags). `path`: where it is to be written (for error messages)."""
    missing = [c for c in ROBOT_COLUMNS if c not in table.columns]
    if missing:
        raise IngestError(path, f"robot table lacks columns {missing}")
    if table[["trial", "seed"]].drop_duplicates().shape[0] > 1:
        raise IngestError(path, "robot table holds more than one run (trial, seed)")
    t = table.sort_values("time_s")

    def cols(*names: str) -> np.ndarray:
        return t[list(names)].to_numpy(float)

    cmd = cols("cmd_speed_mps", "cmd_yaw_rate_rps")
    wrench = cols("harness_fx_n", "harness_fy_n", "harness_fz_n", "harness_tx_nm", "harness_ty_nm",
                  "harness_tz_nm")
    return RobotLog(Path(path), cols("time_s")[:, 0], cols("e_x_m", "e_y_m", "e_z_m"),
                    cols("base_x_m", "base_y_m"), cols("base_yaw_rad")[:, 0],
                    None if np.isnan(wrench).all() else wrench, None if np.isnan(cmd).all() else cmd,
                    t["fall"].to_numpy(bool), t["locked"].to_numpy(bool))


def log_from_markers(markers: dict[str, np.ndarray], time_s: np.ndarray, rm: RobotMarkers, rate_hz: float,
                     max_gap_s: float, origin: str) -> RobotLog:
    """The robot log that markers on the robot give (`ingest.subject.RobotMarkers`), canonical frame:
    base position = the base markers' midpoint, yaw = the heading from the rear to the front marker,
    arm = the arm-end marker in the base frame minus the neutral point. Gaps up to `max_gap_s` are
    filled (`ingest.gaps.fill_short`); a longer gap is an error naming `origin`."""
    missing = [n for n in rm.names if n not in markers]
    if missing:
        raise IngestError(origin, f"robot markers {missing} are not in the marker file")
    front, rear, arm = (fill_short(markers[n], rate_hz, max_gap_s) for n in rm.names)
    if not all(np.isfinite(x).all() for x in (front, rear, arm)):
        raise IngestError(origin, f"robot markers {', '.join(rm.names)} have gaps longer than {max_gap_s} s")
    base = (front + rear) / 2
    yaw = np.unwrap(np.arctan2(front[:, 1] - rear[:, 1], front[:, 0] - rear[:, 0]))
    d = arm - base
    c, s = np.cos(yaw), np.sin(yaw)
    in_base = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])
    return RobotLog(Path(origin), np.asarray(time_s, float), in_base - np.asarray(rm.neutral_in_base_m),
                    base[:, :2], yaw)
