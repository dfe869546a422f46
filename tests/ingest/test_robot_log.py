"""The robot log of a real robot-assisted trial: the v1 CSV format (read, write, checks) and its
resampling onto the mocap samples as the robot table the metrics read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ingest.errors import IngestError
from ingest.readers import RobotLog, read_robot_log, write_robot_log
from ingest.robot import ROBOT_COLUMNS
from ingest.robot_log import robot_table

HEADER = "time [s],arm_forward [m],arm_lateral [m],arm_vertical [m],base_x [m],base_y [m],base_yaw [rad]"


def _log(n: int = 50, rate_hz: float = 100.0, t0: float = 0.0, *, full: bool = True) -> RobotLog:
    """A base moving at 0.8 m/s along heading 0.3 rad while turning at 0.2 rad/s; arm and flags synthetic."""
    rng = np.random.default_rng(0)
    t = t0 + np.arange(n) / rate_hz
    yaw = 0.3 + 0.2 * (t - t0)
    heading = 0.3
    xy = np.column_stack([0.8 * np.cos(heading) * t, 0.8 * np.sin(heading) * t])
    arm = np.column_stack([0.01 + 0.1 * t, -0.02 * t, 0.005 * np.ones(n)])
    fall = np.zeros(n, bool)
    fall[n // 2:] = True
    return RobotLog(
        path=Path("synthetic"), time_s=t, arm_m=arm, base_xy_m=xy, base_yaw_rad=yaw,
        wrench=rng.normal(size=(n, 6)) if full else None, cmd=rng.normal(size=(n, 2)) if full else None,
        fall=fall if full else None, locked=(np.arange(n) % 7 == 0) if full else None)


def _same(a: RobotLog, b: RobotLog) -> None:
    for field in ("time_s", "arm_m", "base_xy_m", "base_yaw_rad", "wrench", "cmd", "fall", "locked"):
        x, y = getattr(a, field), getattr(b, field)
        if x is None or y is None:
            assert x is None and y is None, field
        else:
            assert x.dtype.kind == y.dtype.kind and x.shape == y.shape, field
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), field


def _write(tmp_path: Path, text: str, name: str = "robot_log.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _rows(n: int = 5, dt: float = 0.01) -> list[str]:
    return [f"{i * dt:.3f},0.01,0.02,0.03,{i * dt:.4f},0,0.1" for i in range(n)]


def _bad(path: Path, *fragments: str):
    """Read `path`; the error must name the file and carry every fragment."""
    with pytest.raises(IngestError) as info:
        read_robot_log(path)
    message = str(info.value)
    assert path.name in message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


# --- the format --------------------------------------------------------------------------------

@pytest.mark.parametrize("full", [True, False])
def test_round_trip_is_exact(tmp_path, full):
    log = _log(full=full)
    write_robot_log(tmp_path / "out.csv", log)
    assert (tmp_path / "out.csv").read_text().splitlines()[0] == "# gaitloop robot log v1"
    back = read_robot_log(tmp_path / "out.csv")
    _same(back, log)
    assert back.path == tmp_path / "out.csv"


def test_round_trip_forces_only_and_missing_samples(tmp_path):
    """A load cell without torques: torques NaN; a dropped command sample stays NaN."""
    log = _log()
    wrench = log.wrench.copy()
    wrench[:, 3:] = np.nan
    cmd = log.cmd.copy()
    cmd[3] = np.nan
    log = RobotLog(log.path, log.time_s, log.arm_m, log.base_xy_m, log.base_yaw_rad, wrench, cmd, None, None)
    write_robot_log(tmp_path / "out.csv", log)
    header = (tmp_path / "out.csv").read_text().splitlines()[1]
    assert "harness_fx [N]" in header and "harness_tx" not in header and "fall" not in header
    _same(read_robot_log(tmp_path / "out.csv"), log)


def test_units_are_converted(tmp_path):
    text = ("# lab robot, firmware 2.1\n#\n"
            "time [ms], base_yaw [deg],arm_forward [cm],arm_lateral [mm],arm_vertical [m],base_x [mm],"
            "base_y [cm],harness_tx [Nm],harness_ty [N.m],harness_tz [N m],cmd_speed [m/s],"
            "cmd_yaw_rate [deg/s],locked [-]\n"
            "0,90,10,20,0.03,1000,100,1,2,3,0.5,180,0\n"
            "10,180,10,20,0.03,2000,200,1,2,3,,180,1\n")
    log = read_robot_log(_write(tmp_path, text))
    np.testing.assert_allclose(log.time_s, [0.0, 0.01])
    np.testing.assert_allclose(log.base_yaw_rad, [np.pi / 2, np.pi])
    np.testing.assert_allclose(log.arm_m[0], [0.1, 0.02, 0.03])
    np.testing.assert_allclose(log.base_xy_m[1], [2.0, 2.0])
    assert np.isnan(log.wrench[:, :3]).all()
    np.testing.assert_allclose(log.wrench[0, 3:], [1, 2, 3])
    assert np.isnan(log.cmd[1, 0])
    np.testing.assert_allclose(log.cmd[:, 1], np.pi)
    assert log.fall is None and log.locked.tolist() == [False, True]


# --- resampling onto the mocap samples ---------------------------------------------------------

def test_table_on_coinciding_times_copies_values():
    log = _log()
    table = robot_table(log, log.time_s + 1e-12, "s01", "pid", "t1")
    assert list(table.columns) == ROBOT_COLUMNS
    assert len(table) == len(log.time_s)
    assert (table["source"] == "real").all() and (table["human_mode"] == "none").all()
    assert (table["seed"] == 0).all() and table["seed"].dtype == np.int64
    assert table["fall"].dtype == bool and table["locked"].dtype == bool
    assert np.array_equal(table[["e_x_m", "e_y_m", "e_z_m"]].to_numpy(), log.arm_m)
    assert np.array_equal(table["base_yaw_rad"].to_numpy(), log.base_yaw_rad)
    assert np.array_equal(table.filter(like="harness_").to_numpy(), log.wrench)
    assert np.array_equal(table[["cmd_speed_mps", "cmd_yaw_rate_rps"]].to_numpy(), log.cmd)
    assert np.array_equal(table["fall"].to_numpy(), log.fall)
    assert np.array_equal(table["locked"].to_numpy(), log.locked)
    assert table[["pelvis_x_m", "pelvis_y_m"]].isna().all().all()


def test_table_on_denser_offset_times_interpolates():
    log = _log(n=60, rate_hz=50.0, t0=2.0)  # 2.00 .. 3.18 s
    mocap = np.arange(2.005, 3.18, 1 / 200)  # 200 Hz, offset from the log's samples
    table = robot_table(log, mocap, "s01", "pid", "t1")
    assert len(table) == len(mocap) and np.array_equal(table["time_s"].to_numpy(), mocap)
    np.testing.assert_allclose(table["e_x_m"], 0.01 + 0.1 * mocap, atol=1e-12)
    np.testing.assert_allclose(table["base_x_m"], 0.8 * np.cos(0.3) * mocap, atol=1e-12)
    np.testing.assert_allclose(table["base_yaw_rad"], 0.3 + 0.2 * (mocap - 2.0), atol=1e-12)
    np.testing.assert_allclose(table["base_yaw_rate_rps"], 0.2, atol=1e-9)
    # moving at 0.8 m/s along 0.3 rad while the heading is 0.3 + 0.2 (t - 2) rad
    np.testing.assert_allclose(table["base_speed_mps"], 0.8 * np.cos(0.2 * (mocap - 2.0)), atol=1e-4)
    assert table[["pelvis_x_m", "pelvis_y_m"]].isna().all().all()


def test_flags_hold_the_previous_sample_and_absent_groups_are_nan_or_false():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    z = np.zeros(4)
    log = RobotLog(Path("x.csv"), t, np.zeros((4, 3)), np.zeros((4, 2)), z,
                   fall=np.array([False, False, True, True]))
    mocap = np.array([0.0, 0.05, 0.099, 0.1, 0.15, 0.199, 0.2, 0.3, 0.34])
    table = robot_table(log, mocap, "s01", "free", "t1")
    assert table["fall"].tolist() == [False] * 6 + [True] * 3
    assert table["locked"].dtype == bool and not table["locked"].any()
    assert table.filter(like="harness_").isna().all().all()
    assert table[["cmd_speed_mps", "cmd_yaw_rate_rps"]].isna().all().all()


def test_yaw_is_unwrapped_before_interpolating():
    t = np.array([0.0, 0.1, 0.2])
    yaw = np.array([3.0, -3.2, -3.0])  # turning left through +pi: unwrapped 3.0, 3.083, 3.283
    log = RobotLog(Path("x.csv"), t, np.zeros((3, 3)), np.zeros((3, 2)), yaw)
    table = robot_table(log, np.array([0.05, 0.15]), "s01", "free", "t1")
    unwrapped = np.unwrap(yaw)
    np.testing.assert_allclose(table["base_yaw_rad"], (unwrapped[:2] + unwrapped[1:]) / 2)
    assert (table["base_yaw_rate_rps"] > 0).all()


def test_log_shorter_than_the_mocap(tmp_path):
    path = tmp_path / "short_log.csv"
    write_robot_log(path, _log(n=50, rate_hz=100.0))  # 0 .. 0.49 s
    log = read_robot_log(path)
    robot_table(log, np.arange(0.0, 0.495, 0.005), "s01", "pid", "t1")  # within half a sample: fine
    for mocap in (np.arange(0.0, 0.6, 0.005), np.arange(-0.1, 0.4, 0.005)):
        with pytest.raises(IngestError) as info:
            robot_table(log, mocap, "s01", "pid", "t1")
        assert "short_log.csv" in str(info.value) and "robot log covers 0.000..0.490 s" in str(info.value)
        assert "the mocap trial" in str(info.value)


# --- bad inputs --------------------------------------------------------------------------------

def test_missing_columns_are_all_listed(tmp_path):
    header = "time [s],arm_forward [m],arm_vertical [m],base_x [m],base_y [m]"
    rows = [",".join(r.split(",")[:5]) for r in _rows()]
    _bad(_write(tmp_path, "\n".join([header, *rows])), "missing required columns: arm_lateral, base_yaw")


def test_arm_in_degrees_is_a_wrong_unit(tmp_path):
    path = _write(tmp_path, "\n".join([HEADER.replace("arm_forward [m]", "arm_forward [deg]"), *_rows()]))
    _bad(path, "'arm_forward'", "'deg'", "'m', 'cm', 'mm'")


def test_time_in_minutes_is_a_wrong_unit(tmp_path):
    _bad(_write(tmp_path, "\n".join([HEADER.replace("time [s]", "time [min]"), *_rows()])),
         "'time'", "'min'", "'s', 'ms'")


def test_time_not_increasing(tmp_path):
    rows = _rows()
    rows[3] = rows[3].replace("0.030,", "0.020,", 1)
    _bad(_write(tmp_path, "\n".join([HEADER, *rows])), "time not strictly increasing", "line 5",
         "0.02 s after 0.02 s")


def test_partial_load_cell_group(tmp_path):
    header = HEADER + ",harness_fx [N],harness_fz [N],harness_tx [N m],harness_ty [N m],harness_tz [N m]"
    rows = [r + ",1,2,3,4,5" for r in _rows()]
    _bad(_write(tmp_path, "\n".join([header, *rows])), "partial load-cell force group", "missing harness_fy")


def test_partial_command_group(tmp_path):
    rows = [r + ",0.5" for r in _rows()]
    _bad(_write(tmp_path, "\n".join([HEADER + ",cmd_speed [m/s]", *rows])),
         "partial command group", "missing cmd_yaw_rate")


def test_non_numeric_cell(tmp_path):
    rows = _rows()
    rows[2] = rows[2].replace("0.02,", "abc,", 1)
    _bad(_write(tmp_path, "\n".join(["# comment", HEADER, *rows])), "non-numeric cell 'abc'",
         "'arm_lateral'", "line 5")


def test_unknown_column_lists_the_known_ones(tmp_path):
    rows = [r + ",1" for r in _rows()]
    _bad(_write(tmp_path, "\n".join([HEADER + ",battery [V]", *rows])), "unknown column 'battery'",
         "known: time, arm_forward", "harness_fx", "locked")


def test_duplicate_column(tmp_path):
    rows = [r + ",0" for r in _rows()]
    _bad(_write(tmp_path, "\n".join([HEADER + ",base_x [m]", *rows])), "duplicate column 'base_x'")


def test_header_cell_without_unit(tmp_path):
    _bad(_write(tmp_path, "\n".join([HEADER.replace("base_y [m]", "base_y"), *_rows()])),
         "'base_y' is not 'name [unit]'")


def test_empty_and_comment_only_files(tmp_path):
    _bad(_write(tmp_path, "", "empty.csv"), "empty")
    _bad(_write(tmp_path, "# gaitloop robot log v1\n\n", "comments.csv"), "empty")


def test_unreadable_file(tmp_path):
    _bad(tmp_path / "nowhere.csv", "cannot read file")
    (tmp_path / "latin1.csv").write_bytes("time [s]\n\xe9".encode("latin-1"))
    _bad(tmp_path / "latin1.csv", "not UTF-8")


def test_fewer_than_two_rows(tmp_path):
    _bad(_write(tmp_path, "\n".join([HEADER, *_rows(1)])), "1 data rows", "at least 2")


def test_flags_must_be_zero_or_one(tmp_path):
    rows = [r + f",{v}" for r, v in zip(_rows(), [0, 1, 2, 0, 1], strict=True)]
    _bad(_write(tmp_path, "\n".join([HEADER + ",fall [-]", *rows])), "flag 'fall' is '2'", "line 4",
         "0 or 1")


def test_empty_or_nan_in_a_required_column(tmp_path):
    rows = _rows()
    rows[1] = rows[1].replace(",0.1", ",")
    _bad(_write(tmp_path, "\n".join([HEADER, *rows])), "empty cell", "'base_yaw'", "line 3")
    rows = _rows()
    rows[2] = rows[2].replace("0.03,", "nan,", 1)
    _bad(_write(tmp_path, "\n".join([HEADER, *rows]), "nan.csv"), "NaN", "'arm_vertical'", "line 4")


def test_row_with_wrong_cell_count(tmp_path):
    rows = _rows()
    rows[1] += ",7"
    _bad(_write(tmp_path, "\n".join([HEADER, *rows])), "line 3 has 8 cells, the header 7")
