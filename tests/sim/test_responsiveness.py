"""The robot twin's follow-me responsiveness (sim/robot/responsiveness.py): the twin's own point changes
nothing; a drive time constant sets drive gain = base mass / tau (yaw alike); PID gains scale, other
controllers' do not; bad levels are refused with the value."""

from __future__ import annotations

import math

import pytest

from sim.errors import SimulationError
from sim.robot.responsiveness import (
    Responsiveness,
    for_controller,
    twin_responsiveness,
    with_responsiveness,
)


@pytest.fixture(scope="module")
def twin(params, controller_specs):
    return params.robot.build(), controller_specs


def test_twin_point_is_the_params_robot(twin):
    robot, controllers = twin
    point = twin_responsiveness(robot)
    assert point == Responsiveness(0.025, 0.03, 1.0)  # 100 kg / 4000 N s/m, params robot.base
    moved, specs = with_responsiveness(robot, controllers, point)
    assert moved == robot
    assert specs == controllers


def test_slower_base_and_latency(twin):
    robot, controllers = twin
    moved, _ = with_responsiveness(robot, controllers, Responsiveness(0.4, 0.3, 1.0))
    b = moved.base
    assert math.isclose(b.drive_gain_n_per_mps, robot.base.mass_kg / 0.4)
    assert math.isclose(b.yaw_gain_nm_per_radps, robot.base.yaw_gain_nm_per_radps * 0.025 / 0.4)
    assert b.latency_s == 0.3
    assert moved.arm == robot.arm and moved.harness == robot.harness


def test_pid_gains_scale_and_adaptive_does_not(twin):
    robot, controllers = twin
    _, specs = with_responsiveness(robot, controllers, Responsiveness(0.025, 0.03, 0.25))
    pid, base = specs["pid"]["gains"], controllers["pid"]["gains"]
    for k in ("kp_x", "ki_x", "kd_x", "kp_y", "ki_y", "kd_y"):
        assert math.isclose(pid[k], 0.25 * base[k])
    assert pid["i_max"] == base["i_max"]
    assert specs["adaptive"] == controllers["adaptive"]
    point = Responsiveness(0.1, 0.03, 0.25)
    assert for_controller(point, controllers["adaptive"]) == Responsiveness(0.1, 0.03, 1.0)
    assert for_controller(point, controllers["pid"]) == point


@pytest.mark.parametrize(("point", "message"), [
    ((0.0, 0.03, 1.0), "drive_tau_s must be a finite number > 0. Got 0.0"),
    ((0.1, -0.01, 1.0), "latency_s must be a finite number >= 0. Got -0.01"),
    ((0.1, 0.03, math.nan), "pid_gain_scale must be a finite number > 0. Got nan"),
])
def test_bad_levels_refused(point, message):
    with pytest.raises(SimulationError, match=message):
        Responsiveness(*point)


def test_unknown_factor(twin):
    with pytest.raises(SimulationError, match="no factor 'mass'"):
        twin_responsiveness(twin[0]).moved("mass", 2.0)
