"""The robot table: what a follow-me robot did during a trial, one row per sample.

The simulation writes it from its sensors (`sim.rollout.loop`); a real robot-assisted trial gets
it from the robot's log (`ingest.robot_log`). The metrics read one layout, so real and simulated
robot trials go through the same code (Table I, harness forces, per-phase compliance).

Columns (`ROBOT_COLUMNS`), robot frame = the base's heading (x forward, y left, z up):
- `e_x_m`, `e_y_m`, `e_z_m`: the arm's joint positions from its neutral point (forward, lateral,
  vertical), as the arm's encoders measure them: the robot's tracking error (Wang, Chan et al.,
  ICRA 2025, Table I), real and simulated alike;
- `pelvis_x_m`, `pelvis_y_m`: the harness point on the pelvis relative to the neutral point (the
  simulation knows it exactly; NaN for real trials, where only the arm is measured);
- `base_x_m`, `base_y_m`, `base_yaw_rad`, `base_speed_mps`, `base_yaw_rate_rps`: base pose and
  velocity (odometry);
- `cmd_speed_mps`, `cmd_yaw_rate_rps`: the controller's command (NaN when not logged);
- `harness_*`: the wrench the harness exerts on the pelvis, robot frame (N, N m; NaN without a
  load cell);
- `fall`, `locked`: fall detected, arm locked.
"""

from __future__ import annotations

ROBOT_ID_COLUMNS = ["subject", "source", "human_mode", "condition", "trial", "seed"]
ROBOT_SIGNAL_COLUMNS = ["e_x_m", "e_y_m", "e_z_m", "pelvis_x_m", "pelvis_y_m", "base_x_m", "base_y_m",
                        "base_yaw_rad", "base_speed_mps", "base_yaw_rate_rps", "cmd_speed_mps",
                        "cmd_yaw_rate_rps", "harness_fx_n", "harness_fy_n", "harness_fz_n", "harness_tx_nm",
                        "harness_ty_nm", "harness_tz_nm"]
ROBOT_COLUMNS = [*ROBOT_ID_COLUMNS, "time_s", *ROBOT_SIGNAL_COLUMNS, "fall", "locked"]
HARNESS_COLUMNS = ROBOT_SIGNAL_COLUMNS[-6:]

__all__ = ["HARNESS_COLUMNS", "ROBOT_COLUMNS", "ROBOT_ID_COLUMNS", "ROBOT_SIGNAL_COLUMNS"]
