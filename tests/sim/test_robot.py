"""MRBA twin: structure, harness wrench (F = k q + d q' inside the limits, constraint at them), base drive."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.motion.synthetic import capsule_world
from sim.robot.harness import AXES, HarnessIndex, harness_wrench, wrench_from_sensors
from sim.robot.mrba import SENSOR_WIDTH, SENSORS, BaseDrive, RobotIndex, attach_robot, lock_arm

MASS_KG = 75.0


@pytest.fixture(scope="module")
def robot(params):
    return params.robot.build()


def world(robot, gravity: bool = True):
    spec = capsule_world(MASS_KG, 0.95)
    attach_robot(spec, robot, "pelvis")
    spec.option.timestep = 0.002
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    if not gravity:
        spec.option.gravity = [0, 0, 0]
    model = spec.compile()
    return model, mujoco.MjData(model)


def test_robot_names_are_prefixed_and_sizes_match_params(robot):
    model, data = world(robot)
    spec = capsule_world(MASS_KG, 0.95)
    before = {spec.joints[i].name for i in range(len(spec.joints))}
    attach_robot(spec, robot)
    added = [j.name for j in spec.joints if j.name not in before]
    added += [a.name for a in spec.actuators] + [e.name for e in spec.equalities]
    assert added and all(n.startswith("mrba_") for n in added)
    base = RobotIndex.of(model).base_body
    robot_mass = model.body_subtreemass[base]
    assert robot_mass == pytest.approx(robot.base.mass_kg + robot.harness.mass_kg, rel=0.01)
    mujoco.mj_forward(model, data)
    neutral = data.site_xpos[RobotIndex.of(model).neutral_site]
    pelvis = data.xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")]
    assert np.allclose(neutral, pelvis, atol=1e-9)  # the arm's neutral point is at the pelvis
    chassis = model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "mrba_chassis")]
    assert 2 * chassis[1] == pytest.approx(robot.base.width_m)


def test_harness_wrench_is_k_q_plus_d_qdot_inside_limits(robot):
    model, data = world(robot, gravity=False)
    h = HarnessIndex.of(model)
    rng = np.random.default_rng(1)
    k, d = np.array(robot.harness.stiffness), np.array(robot.harness.damping)
    for _ in range(5):
        q = rng.uniform(-0.8, 0.8, 6) * np.array(robot.harness.range)
        qd = rng.normal(0, 0.2, 6)
        data.qpos[h.qpos], data.qvel[h.dof] = q, qd
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(harness_wrench(data, h), k * q + d * qd, rtol=1e-9, atol=1e-9)


def test_harness_limit_adds_constraint_force(robot):
    """Hanging a 75 kg body from the locked arm: the spring alone (k z at the 5 cm limit) cannot carry
    it, so the wrench must include the limit force and balance the weight."""
    model, data = world(robot)
    idx, h = RobotIndex.of(model), HarnessIndex.of(model)
    mujoco.mj_forward(model, data)
    lock_arm(model, data, idx)
    data.ctrl[:] = 0
    mujoco.mj_step(model, data, nstep=1500)
    wrench = harness_wrench(data, h)
    weight = MASS_KG * 9.81
    assert robot.harness.stiffness[2] * robot.harness.range[2] < weight  # premise of the test
    assert data.qpos[h.qpos[2]] <= -robot.harness.range[2] + 2e-3
    assert wrench[2] == pytest.approx(-weight, rel=0.03)
    assert abs(data.qpos[idx.arm_qpos[2]]) < 1e-3  # the lock holds the arm
    # the rollouts' recorded form: the same wrench from the robot's sensor block (limit force included)
    np.testing.assert_allclose(sensor_wrench(model, data), wrench, atol=0.02 * weight)


def sensor_wrench(model, data) -> np.ndarray:
    idx, h = RobotIndex.of(model), HarnessIndex.of(model)
    block = data.sensordata[idx.sensor_adr:idx.sensor_adr + SENSOR_WIDTH][None]

    def part(name):
        a, w = SENSORS[name]
        return block[:, a:a + w]

    return wrench_from_sensors(model, h, part("harness_pos"), part("harness_vel"), part("harness_limit"))[0]


def test_sensor_block_matches_the_simulator_state(robot):
    """e (pelvis in the neutral-point frame), odometry and harness wrench from the sensors equal what
    the simulator state gives, with the base turned and the harness deflected inside its limits."""
    model, data = world(robot, gravity=False)
    idx, h = RobotIndex.of(model), HarnessIndex.of(model)
    rng = np.random.default_rng(3)
    data.qpos[idx.base_qpos] = (0.2, -0.1, 0.7)
    data.qpos[idx.arm_qpos] = (0.05, -0.03, 0.02)
    data.qpos[h.qpos] = rng.uniform(-0.5, 0.5, 6) * np.array(robot.harness.range)
    data.qvel[h.dof] = rng.normal(0, 0.2, 6)
    data.qvel[idx.base_dof] = (0.5, 0.2, 0.3)
    mujoco.mj_forward(model, data)
    block = data.sensordata[idx.sensor_adr:idx.sensor_adr + SENSOR_WIDTH]
    yaw = 0.7
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    d = data.xpos[pelvis] - data.site_xpos[idx.neutral_site]
    rot = np.array([[np.cos(yaw), np.sin(yaw), 0], [-np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    np.testing.assert_allclose(block[:3], rot @ d, atol=1e-9)
    np.testing.assert_allclose(block[3:6], data.qpos[idx.base_qpos], atol=1e-12)
    np.testing.assert_allclose(block[6:9], data.qvel[idx.base_dof], atol=1e-12)
    np.testing.assert_allclose(sensor_wrench(model, data), harness_wrench(data, h), atol=1e-9)


def test_base_drive_latency_and_acceleration_limit(robot):
    model, data = world(robot, gravity=False)
    idx = RobotIndex.of(model)
    data.eq_active[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "mrba_harness_weld")] = 0
    dt = 0.01
    drive = BaseDrive(robot.base, dt)
    n_delay = int(round(robot.base.latency_s / dt))
    speeds = []
    for _ in range(150):
        drive.step(1.0, 0.0)
        drive.apply(data, idx)
        mujoco.mj_step(model, data, nstep=5)
        speeds.append(data.qvel[idx.base_dof[0]])
    refs = np.array(speeds)
    assert np.all(np.abs(refs[:n_delay]) < 1e-3)  # nothing moves before the latency has passed
    assert refs[-1] == pytest.approx(1.0, abs=0.02)
    assert np.max(np.diff(refs)) / dt < robot.base.max_accel_mps2 * 1.3


def test_base_is_stiff_against_harness_loads(robot):
    """A 50 N sideways pull (a strong harness load) moves the velocity-servoed 100 kg base < 2 cm/s."""
    model, data = world(robot, gravity=False)
    idx = RobotIndex.of(model)
    eq = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, "mrba_harness_weld")
    data.eq_active[eq] = 0
    data.xfrc_applied[idx.base_body] = [0, 50, 0, 0, 0, 0]
    mujoco.mj_step(model, data, nstep=1000)
    assert abs(data.qvel[idx.base_dof[1]]) < 0.02
    assert set(AXES) == {"x", "y", "z", "roll", "pitch", "yaw"}
