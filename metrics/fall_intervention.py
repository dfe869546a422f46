"""How the robot met one scripted balance loss, and how often it locked the arm for nothing.

Per rollout with an event (`sim.body.balance_loss`): whether the fall rule fired within
`detection_window_s` of the onset, the latency from onset to the arm's lock, how far the pelvis had
dropped below its walking height at the lock and at worst afterwards, and the largest harness
force from the onset on; it is caught when detected with the pelvis at most `caught_drop_m` down
(the fall rule's drop threshold plus a margin, params `fall_intervention.caught_margin_m`). A
rollout whose human fell, or whose arm locked, before the onset did not meet the event walking: it
is marked and left out of the rates. Without an event, every lock is an
alarm; an alarm that the human's own fall (pelvis below the fall height or trunk past its tilt
limit, `sim.learn.policy_human`) does not follow within `confirm_s` is a false alarm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

EVENT_COLUMNS = ["event", "onset_s", "human_fall_s", "robot_fall_s", "before_onset", "detected", "caught",
                 "latency_s",
                 "pelvis_drop_at_lock_m", "max_pelvis_drop_m", "max_harness_force_n", "false_alarm", "walk_s"]


@dataclass(frozen=True)
class FallRuleParams:
    detection_window_s: float = 1.5  # a lock this long after the onset counts as its detection
    confirm_s: float = 1.0           # an alarm the human's fall does not follow this soon is false
    baseline_s: float = 2.0          # walking pelvis height: the mean over this long before the onset
    caught_drop_m: float = 0.22      # caught: detected with the pelvis at most this far down at the lock


def _nan(x: float | None) -> float:
    return np.nan if x is None else float(x)


def event_metrics(event: str, onset_s: float | None, time_s: np.ndarray, pelvis_z: np.ndarray,
                  robot: pd.DataFrame, robot_fall_s: float | None, human_fall_s: float | None,
                  p: FallRuleParams | None = None) -> dict:
    """One rollout's row (`EVENT_COLUMNS`); `event` "none" for normal walking (onset None)."""
    p = p or FallRuleParams()
    t = np.asarray(time_s, float)
    z = np.asarray(pelvis_z, float)
    end = t[-1] if len(t) else 0.0
    out = dict.fromkeys(EVENT_COLUMNS, np.nan)
    out.update(event=event, onset_s=_nan(onset_s), human_fall_s=_nan(human_fall_s),
               robot_fall_s=_nan(robot_fall_s), before_onset=False, detected=False, caught=False,
               false_alarm=False)
    if onset_s is None:
        out["walk_s"] = float(min(end, robot_fall_s if robot_fall_s is not None else end))
        if robot_fall_s is not None:
            out["false_alarm"] = human_fall_s is None or human_fall_s > robot_fall_s + p.confirm_s
        return out
    first = min(x for x in (robot_fall_s, human_fall_s, np.inf) if x is not None)
    out["walk_s"] = float(min(end, onset_s))
    if first < onset_s:
        out["before_onset"] = True
        return out
    ref = z[(t >= onset_s - p.baseline_s) & (t < onset_s)]
    z0 = float(ref.mean()) if len(ref) else float(np.interp(onset_s, t, z))
    after = t >= onset_s
    out["max_pelvis_drop_m"] = float(z0 - z[after].min()) if after.any() else np.nan
    if robot_fall_s is not None:
        out["detected"] = robot_fall_s <= onset_s + p.detection_window_s
        out["latency_s"] = float(robot_fall_s - onset_s)
        out["pelvis_drop_at_lock_m"] = float(z0 - np.interp(robot_fall_s, t, z))
        out["caught"] = bool(out["detected"] and out["pelvis_drop_at_lock_m"] <= p.caught_drop_m)
    if not robot.empty:
        r = robot[robot["time_s"].to_numpy(float) >= onset_s]
        f = np.linalg.norm(r[["harness_fx_n", "harness_fy_n", "harness_fz_n"]].to_numpy(float), axis=1)
        out["max_harness_force_n"] = float(f.max()) if len(f) else np.nan
    return out
