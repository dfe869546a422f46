"""Follow-me controllers: registry (names, import paths, a controller defined here), LQR stability,
the adaptive speed observer on the synthetic walk, and a comparison through the same rollout."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import SimulationError
from sim.motion.replay import ReplayHuman
from sim.motion.synthetic import WalkParams, capsule_world, synthetic_walk
from sim.robot.controllers import (
    PID,
    Adaptive,
    BaseCommand,
    Controller,
    RobotSensors,
    make_controller,
    register,
    resolve,
)
from sim.robot.controllers.adaptive import SPEED_GRID_MPS, forward_gain, lateral_gain, scheduled_gains
from sim.robot.controllers.gains import searched
from sim.rollout.loop import RolloutParams, rollout
from sim.rollout.tuning import score
from sim.rollout.world import robot_info


class FeedForwardP(Controller):
    """A controller written in this test file: proportional only on the deflection."""

    def reset(self) -> None:
        self.steps = 0

    def step(self, s: RobotSensors) -> BaseCommand:
        self.steps += 1
        return BaseCommand(self.gains["k"] * s.arm_q[0], 0.5 * self.gains["k"] * s.arm_q[1])


class RecordingAdaptive(Adaptive):
    def reset(self) -> None:
        super().reset()
        self.log: list[tuple[float, float]] = []

    def step(self, s: RobotSensors) -> BaseCommand:
        cmd = super().step(s)
        self.log.append((s.time_s, self.speed_mps, self.stride_s))
        return cmd


@pytest.fixture(scope="module")
def setup(params, controller_specs):
    return params.robot.build(), params.rollout.replay, controller_specs


TEST_WALK = WalkParams(duration_s=8.0)


def walk_rollout(controller, robot, replay, seed=0, walk=TEST_WALK):
    return rollout(capsule_world(walk.mass_kg), ReplayHuman(synthetic_walk(walk), replay), controller,
                   RolloutParams(robot=robot, sample_rate_hz=100.0), seed)


def test_registry_by_name_and_import_path():
    assert resolve("pid") is PID and resolve("adaptive") is Adaptive
    assert resolve("sim.robot.controllers.pid:PID") is PID
    assert resolve(f"{FeedForwardP.__module__}:FeedForwardP") is FeedForwardP
    register("feedforward_p", FeedForwardP)
    assert resolve("feedforward_p") is FeedForwardP


def test_registry_errors_name_the_controller(params):
    with pytest.raises(SimulationError, match="controller 'nope': unknown"):
        resolve("nope")
    with pytest.raises(SimulationError, match="cannot import"):
        resolve("sim.robot.controllers.pid:Missing")
    with pytest.raises(SimulationError, match="not a Controller subclass"):
        resolve("numpy:ndarray")
    with pytest.raises(SimulationError, match="lacks 'class'"):
        make_controller({"gains": {}}, robot_info(params.robot.build(), 100.0))


def test_gains_are_declared_checked_and_defaulted(setup):
    robot, _, specs = setup
    info = robot_info(robot)
    for cls in (PID, Adaptive):  # every declared gain: a meaning, a unit, bounds around its default
        for name, g in cls.declared_gains.items():
            assert g.meaning and g.unit, name
            assert g.default is None or g.bounds[0] <= g.default <= g.bounds[1], name
    assert list(searched(PID)) == ["kp_x", "ki_x", "kd_x", "kp_y", "ki_y", "kd_y"]
    assert {g.search for g in searched(Adaptive).values()} == {"linear"}  # LQR weights: log10 already
    ctrl = Adaptive(specs["adaptive"]["gains"], info)
    assert ctrl.gains["stride_min_s"] == 0.6 and ctrl.gains["i_max"] == 0.1  # declared default, params value
    with pytest.raises(SimulationError, match=r"controller Adaptive: gain comb_compensaton: unknown gain"):
        Adaptive({**specs["adaptive"]["gains"], "comb_compensaton": 0.5}, info)  # misspelt: no silent default
    with pytest.raises(SimulationError, match=r"gain kd_y: missing: required gain of PID"):
        make_controller({"class": "pid", "gains": {k: 1.0 for k in ("kp_x", "ki_x", "kd_x", "kp_y", "ki_y")}},
                        info)
    with pytest.raises(SimulationError, match=r"gain i_max: -1\.0 outside \[0, inf\]"):
        PID({**specs["pid"]["gains"], "i_max": -1.0}, info)
    assert FeedForwardP({"anything": 1.0}, info).gains == {"anything": 1.0}  # declares none: takes any


def test_pid_signs(params):
    pid = PID({"kp_x": 2, "ki_x": 0, "kd_x": 0, "kp_y": 3, "ki_y": 0, "kd_y": 0}, robot_info(
        params.robot.build(), 100.0))
    pid.reset()
    s = RobotSensors(0.0, np.array([0.1, -0.05, 0]), np.zeros(3), np.zeros(3), 0.0, 0.0)
    cmd = pid.step(s)
    assert cmd.speed_mps == pytest.approx(0.2) and cmd.yaw_rate_rps == pytest.approx(-0.15)


def test_lqr_closed_loops_are_stable(setup):
    robot, _, _ = setup
    info = robot_info(robot)
    k = forward_gain(info.drive_tau_s, 10.0, 100.0, 1.0)
    a = np.array([[0, 1, 0], [0, 0, -1], [0, 0, -1 / info.drive_tau_s]])
    b = np.array([[0], [0], [1 / info.drive_tau_s]])
    assert np.linalg.eigvals(a - b @ k[None]).real.max() < 0
    for v in SPEED_GRID_MPS:
        kl = lateral_gain(v, info.reach_m, info.drive_tau_s, 10.0, 100.0, 1.0)
        tau = info.drive_tau_s
        al = np.array([[0, 1, 0, 0], [0, 0, -v, -info.reach_m], [0, 0, 0, 1], [0, 0, 0, -1 / tau]])
        bl = np.array([[0], [0], [0], [1 / tau]])
        assert np.linalg.eigvals(al - bl @ kl[None]).real.max() < 0


def test_scheduled_gains_are_the_riccati_solutions_and_are_solved_once(setup):
    info = robot_info(setup[0])
    args = (info.drive_tau_s, info.reach_m, 10.0, 100.0, 1.0, 20.0, 50.0, 2.0)
    scheduled_gains.cache_clear()
    k_fwd, k_lat = scheduled_gains(*args)
    assert k_fwd == tuple(forward_gain(args[0], *args[2:5]).tolist())
    tau, reach = args[:2]
    assert k_lat == tuple(tuple(lateral_gain(v, reach, tau, *args[5:]).tolist()) for v in SPEED_GRID_MPS)
    assert scheduled_gains(*args) is scheduled_gains(*args) and scheduled_gains.cache_info().misses == 1
    assert scheduled_gains(*args[:-1], 3.0)[1] != k_lat  # other weights, other gains


def test_adaptive_speed_estimate_ignores_intra_stride_oscillation(setup):
    robot, replay, specs = setup
    ctrl = RecordingAdaptive(specs["adaptive"]["gains"], robot_info(robot))
    walk = TEST_WALK
    result = walk_rollout(ctrl, robot, replay, walk=walk)
    t, v, _ = np.array(ctrl.log).T
    steady = v[t > walk.rest_s + walk.ramp_s + walk.stride_s * 1.5]
    assert steady.mean() == pytest.approx(walk.speed_mps, rel=0.03)
    # the surge is +-0.05 m/s at step frequency; after the gait-cycle average it must be far smaller
    assert steady.max() - steady.min() < 0.4 * 2 * walk.surge_mps
    assert not result.robot.fall.any()


@pytest.mark.parametrize("stride_s", [0.9, 1.3])
def test_adaptive_estimates_the_stride_period_online(setup, stride_s):
    """The observer's averaging window follows the user's stride (init 1.1 s), from the arm and
    odometry only; with it the stride average of a 0.9 s or 1.3 s stride stays flat."""
    robot, replay, specs = setup
    ctrl = RecordingAdaptive(specs["adaptive"]["gains"], robot_info(robot))
    walk = WalkParams(duration_s=9.0, stride_s=stride_s, surge_mps=0.1, asym_mps=0.04)
    walk_rollout(ctrl, robot, replay, walk=walk)
    t, v, stride = np.array(ctrl.log).T
    late = t > 6.0
    assert np.abs(stride[late] / stride_s - 1).max() < 0.03
    assert v[late].max() - v[late].min() < 0.4 * 2 * walk.surge_mps


def test_custom_controller_runs_through_the_same_rollout_and_is_compared(setup):
    robot, replay, specs = setup
    info = robot_info(robot)
    rows = {}
    for name, spec in {"custom": {"class": f"{FeedForwardP.__module__}:FeedForwardP", "gains": {"k": 8.0}},
                       "pid": specs["pid"], "adaptive": specs["adaptive"]}.items():
        ctrl = make_controller(spec, info)
        result = walk_rollout(ctrl, robot, replay)
        assert result.stable and not result.robot.fall.any()
        rows[name] = score(result, 0.001)[1]
    assert rows["custom"]["mean_abs_e_x_m"] > 0
    # the tuned controllers beat the proportional-only one (steady lag v / k) on the tuning walk
    for tuned in ("pid", "adaptive"):
        assert rows[tuned]["mean_abs_e_x_m"] < rows["custom"]["mean_abs_e_x_m"]
    print({k: {m: round(v, 4) for m, v in r.items() if isinstance(v, float)} for k, r in rows.items()})


def test_curving_tuning_walk_keeps_speed_and_yaws_with_its_path():
    walk = WalkParams(speed_mps=1.4, stride_s=1.05, duration_s=10.0, turn_rate_rps=0.2)
    m = synthetic_walk(walk)
    t, q = m.time_s, m.qpos
    late = t > walk.rest_s + walk.ramp_s + walk.stride_s
    v = np.gradient(q[:, :2], t, axis=0)
    n = int(round(walk.stride_s * walk.rate_hz))
    mean_v = (q[n:, :2] - q[:-n, :2]) / walk.stride_s  # stride-averaged velocity
    assert np.hypot(*mean_v[late[n:]].T).mean() == pytest.approx(walk.speed_mps, rel=0.02)
    yaw = 2 * np.arctan2(q[:, 6], q[:, 3])
    assert np.gradient(np.unwrap(yaw), t)[late].mean() == pytest.approx(walk.turn_rate_rps, rel=0.01)
    assert np.isfinite(v).all()


class HeadingLog(Adaptive):
    """Adaptive recording what its observer returns (speed, heading, heading rate) per tick."""

    def reset(self) -> None:
        super().reset()
        self.log: list[tuple[float, float, float, float]] = []

    def observe(self, s: RobotSensors) -> tuple[float, float, float]:
        out = super().observe(s)
        self.log.append((s.time_s, *out))
        return out


def test_turn_onset_walk_starts_turning_at_its_onset():
    walk = WalkParams(speed_mps=1.5, duration_s=9.0, turn_rate_rps=0.4, turn_onset_s=6.0, turn_ramp_s=2.0)
    m = synthetic_walk(walk)
    yaw_rate = np.gradient(np.unwrap(2 * np.arctan2(m.qpos[:, 6], m.qpos[:, 3])), m.time_s)
    assert np.abs(yaw_rate[m.time_s < 6.0]).max() < 1e-9
    assert yaw_rate[m.time_s > 8.05].mean() == pytest.approx(0.4, rel=0.01)


def test_comb_heading_follows_a_turn_onset_without_the_stride_lag(setup):
    """Entering a turn, the stride average's heading lags about half a stride of turning; the comb
    estimate (velocity now minus one stride ago) removes most of that lag, from robot sensors only."""
    robot, replay, specs = setup
    walk = WalkParams(speed_mps=1.5, stride_s=1.0, surge_mps=0.1, asym_mps=0.05, duration_s=9.0,
                      turn_rate_rps=0.4, turn_onset_s=6.0, turn_ramp_s=2.0)
    m = synthetic_walk(walk)
    true = np.interp(np.arange(0, 9.0, 0.01), m.time_s, np.unwrap(2 * np.arctan2(m.qpos[:, 6], m.qpos[:, 3])))
    errs = {}
    for comb in (0.0, 1.0):
        ctrl = HeadingLog({**specs["adaptive"]["gains"], "comb_compensation": comb}, robot_info(robot))
        walk_rollout(ctrl, robot, replay, walk=walk)
        t, _, heading, rate = np.array(ctrl.log).T
        turning = (t > 7.0) & (t < 8.9)
        truth = np.interp(t, np.arange(0, 9.0, 0.01), true)
        errs[comb] = np.abs(np.angle(np.exp(1j * (heading - truth))))[turning].mean()
        if comb:
            assert rate[turning].mean() == pytest.approx(0.3, abs=0.12)  # the path's rate rises 0.25 -> 0.4
    assert errs[0.0] > 0.1  # ~ half a stride x 0.3-0.4 rad/s
    assert errs[1.0] < 0.5 * errs[0.0]


def test_adaptive_speed_follows_the_start_of_walking(setup):
    """Before a stride period is known, the fed-forward speed comes from a short window: during the
    ramp from rest it lags the walk far less than the average over all that was seen."""
    robot, replay, specs = setup
    walk = TEST_WALK
    lags = {}
    for window in (0.5, 100.0):
        gains = {**specs["adaptive"]["gains"], "startup_window_s": window}
        ctrl = RecordingAdaptive(gains, robot_info(robot))
        walk_rollout(ctrl, robot, replay, walk=walk)
        t, v, _ = np.array(ctrl.log).T
        ramp = (t > walk.rest_s + 0.5) & (t < walk.rest_s + walk.ramp_s)
        u = np.clip((t - walk.rest_s) / walk.ramp_s, 0, 1)
        lags[window] = np.mean((3 * u**2 - 2 * u**3)[ramp] * walk.speed_mps - v[ramp])
    assert lags[0.5] < 0.6 * lags[100.0]
