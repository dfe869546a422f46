"""The steerable walking human: commands, the steered reference, standing, and the warm start
that turns a straight walker into a steering policy without changing what it does."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from sim.learn.steering import (
    lead_heading,
    level_speed_ratio,
    sample_commands,
    speed_law,
    turn_lean_offset,
)
from sim.learn.train import (
    STEERING_FILE,
    STEERING_STATS,
    UNTRAINED_SLOTS,
    make_vec_env,
    new_ppo,
    policy_env,
    save_steering,
    widen_policy,
)
from sim.learn.walk_env import LEGACY_OBS_SIZE, OBS_SIZE, GaitState, make_walk_env, start_phase
from sim.motion.reference import blend_qpos, load_reference
from sim.rollout.scenarios import PHASES, command_profile


@pytest.fixture(scope="module")
def cycle(camargo_model):
    return load_reference(camargo_model / "reference.npz").cycle


@pytest.fixture(scope="module")
def env(train_params, camargo_model, cycle):
    return make_walk_env(camargo_model / "human.xml", cycle, train_params().env, seed=0)


def test_random_commands_cover_every_transition(train_params, cycle):
    tp = train_params()
    rng = np.random.default_rng(0)
    seen: set[str] = set()
    for _ in range(40):
        prof = sample_commands(rng, cycle.speed_mps, tp.env.episode_s, 1 / tp.env.control_dt_s,
                               tp.env.commands, tp.env.profile)
        assert prof.time_s[-1] >= tp.env.episode_s
        lo, hi = tp.env.commands.speed_range
        assert prof.speed_mps.max() <= hi * cycle.speed_mps + 1e-9 and prof.speed_mps.min() >= 0.0
        seen |= set(prof.phase.tolist())
    assert seen == set(PHASES)


def test_quiet_standing_start_stands_on_the_floor(env):
    stand = command_profile("stand", [], env.ref.speed_mps, 1 / env.dt)  # standing only
    env.reset(seed=0, options={"commands": stand, "pushes": False})
    assert env.gait.a == 0.0 and np.allclose(env.data.qvel, 0.0)
    mujoco.mj_forward(env.model, env.data)
    feet = np.isin(env.model.geom_bodyid, env.idx.feet) | np.isin(
        env.model.body_parentid[env.model.geom_bodyid], env.idx.feet)
    lowest = min(env.data.geom_xpos[g, 2] - env.model.geom_rbound[g] for g in np.flatnonzero(feet))
    assert lowest < 0.01  # the bounding spheres reach the floor (the exact bottom is at z = 0)
    _, terms = env._reward()
    assert terms[0] > 0.999 and terms[3] > 0.999  # pose and pelvis height on the standing reference
    phase = env.gait.phase
    env.step(np.zeros(21))
    assert env.gait.phase == phase  # no commanded speed: the cycle does not advance


def test_speed_law_shares_a_slowdown_between_stride_and_cadence():
    assert speed_law(0.0, 0.5, 0.42) == (0.0, 0.0)
    assert speed_law(0.8, 0.5, 0.42) == (1.0, 0.8)  # fast: the stride is kept, the cadence follows
    for ratio in (0.05, 0.2, 0.45):
        a, rate = speed_law(ratio, 0.5, 0.42)
        assert a * rate == pytest.approx(ratio)  # stride x cadence = speed
        assert a == pytest.approx((ratio / 0.5) ** 0.42) and rate > ratio  # shorter, quicker steps
        assert level_speed_ratio(a, 0.5, 0.42) == pytest.approx(ratio)
    a, rate = speed_law(0.25, 0.5, None)  # the legacy law of the policies trained before it
    assert (a, rate) == (0.5, 0.25) and level_speed_ratio(0.5, 0.5, None) == 0.5


def test_a_cadence_floor_keeps_steps_coming_to_the_end_of_a_stop():
    floor = 0.6 ** 0.58  # the law's cadence at 0.6 x the cycle's speed
    for ratio in (0.01, 0.1, 0.3, 0.55):
        a, rate = speed_law(ratio, 1.0, 0.42, floor)
        assert rate == floor and a == pytest.approx(ratio / floor)  # stride shrinks with the speed
        assert a < speed_law(ratio, 1.0, 0.42)[0]  # shorter than without the floor: no collapse at the end
        assert level_speed_ratio(a, 1.0, 0.42, floor) == pytest.approx(ratio)
    assert speed_law(0.8, 1.0, 0.42, floor) == speed_law(0.8, 1.0, 0.42)  # above it: the law itself
    assert level_speed_ratio(0.95, 1.0, 0.42, floor) == level_speed_ratio(0.95, 1.0, 0.42)
    assert speed_law(0.0, 1.0, 0.42, floor) == (0.0, 0.0)  # standing: no steps
    assert level_speed_ratio(0.0, 1.0, 0.42, floor) == 0.0
    a0, _ = speed_law(0.6 * (1 - 1e-9), 1.0, 0.42, floor)  # continuous where the floor takes over
    assert a0 == pytest.approx(speed_law(0.6 * (1 + 1e-9), 1.0, 0.42, floor)[0], rel=1e-6)


def test_a_policy_keeps_the_speed_law_it_was_trained_under(tmp_path, train_params):
    env = train_params().env
    assert env.commands.stride_speed_exponent == 0.42
    assert policy_env(tmp_path, env).commands.stride_speed_exponent is None  # trained before the law
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.3}')
    assert policy_env(tmp_path, env).commands.stride_speed_exponent == 0.3
    assert policy_env(tmp_path, replace(env, commands=replace(env.commands, min_cadence=0.7))
                      ).commands.min_cadence is None  # trained without a floor: none, whatever params say
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42, "min_cadence": 0.74}')
    assert policy_env(tmp_path, env).commands.min_cadence == 0.74


def test_the_first_step_from_standing_can_be_the_left_legs(env, tmp_path, train_params):
    """`first_step` "left": the legs' crossing while the left foot swings, the closest of those
    phases; with the feet's sides swapped the other crossing, half a cycle away. "either": the closer
    of the two crossings, as before (a policy that recorded no side keeps it)."""
    feet = env.ref.feet
    gap = np.abs(feet[:, 0] - feet[:, 3])
    left = start_phase(feet, "left")
    k = int(round(left * len(feet)))
    assert env.ref.start_phase == start_phase(feet, env.p.commands.first_step) and feet[k, 2] > feet[k, 5]
    assert gap[k] == gap[feet[:, 2] > feet[:, 5]].min()
    assert gap[int(round(start_phase(feet, "either") * len(feet)))] == gap.min() <= gap[k]
    swapped = start_phase(feet[:, [3, 4, 5, 0, 1, 2]], "left")
    assert abs((swapped - left) % 1.0 - 0.5) < 0.1
    with pytest.raises(ValueError, match="first_step"):
        start_phase(feet, "right")
    base = train_params().env
    left_env = replace(base, commands=replace(base.commands, first_step="left"))
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42}')
    assert policy_env(tmp_path, left_env).commands.first_step == "either"  # trained before it was recorded
    save_steering(tmp_path, left_env.commands)
    assert policy_env(tmp_path, replace(base, commands=replace(base.commands, first_step="either"))
                      ).commands.first_step == "left"


def test_gait_follows_the_commanded_speed(env):
    """Half the cycle's speed: the phase advances at the law's cadence (with the params' law, strides
    shorten as speed^0.42 below the cycle's speed and the cadence floor 0.744 holds here), stride x
    cadence is the speed, and the root velocity reference halves."""
    env.gait.start(0.2, env.ref.speed_mps, 0.0, 0.0)
    env.gait.advance(0.01, 0.5 * env.ref.speed_mps, 0.3, 0.0, 0.3)
    a, rate = speed_law(0.5, *env.gait.law)
    assert a * rate == pytest.approx(0.5) and 0.5 < rate < 1.0
    assert env.gait.phase == pytest.approx(0.2 + 0.01 * rate)
    assert env.gait.reference[5][0] == pytest.approx(
        0.5 * np.interp(env.gait.phase, np.arange(env.ref.n) / env.ref.n, env.ref.root_vel[:, 0]), rel=0.02)


def test_blend_keeps_unit_quaternions_and_its_ends(env):
    q0, q1 = env.ref.stand_qpos, env.ref.qpos[10]
    assert np.array_equal(blend_qpos(env.model, q0, q1, 0.0), q0)
    assert np.array_equal(blend_qpos(env.model, q0, q1, 1.0), q1)
    mid = blend_qpos(env.model, q0, q1, 0.5)
    for j in range(env.model.njnt):
        kind, adr = env.model.jnt_type[j], env.model.jnt_qposadr[j]
        if kind == mujoco.mjtJoint.mjJNT_BALL:
            assert np.linalg.norm(mid[adr:adr + 4]) == pytest.approx(1.0)


def test_feet_lean_into_a_turn_and_back(env):
    assert turn_lean_offset(0.9, 1.4, 0.0, 1.0, 0.35) == 0.0
    left = turn_lean_offset(0.9, 1.4, np.radians(90.0), 1.0, 0.35)
    assert left == pytest.approx(-0.9 * 1.4 * np.radians(90.0) / 9.81)  # feet outside a left turn
    assert turn_lean_offset(0.9, 1.4, -np.radians(90.0), 1.0, 0.35) == -left
    assert turn_lean_offset(0.9, 5.0, 3.0, 1.0, 0.35) == pytest.approx(-0.9 * 0.35)  # the largest lean taken
    plain = GaitState(env.ref, env.p.commands)
    lean = GaitState(env.ref, replace(env.p.commands, turn_lean=1.0))
    v, w = env.ref.speed_mps, np.radians(90.0)
    for g in (plain, lean):
        g.start(0.3, v, 0.0, 0.0)
    assert np.array_equal(lean.reference[3], plain.reference[3])  # straight: no lean
    for _ in range(60):  # 1.8 s of turning: the lean settles
        for g in (plain, lean):
            g.advance(env.step_phase, v, 0.0, w, 0.0)
    shift = lean.reference[3] - plain.reference[3]
    target = turn_lean_offset(lean.reference[4], v, w, 1.0, 0.35)
    assert shift[1] == shift[4]  # both feet sideways, alike, by the lean of the pelvis height (which
    assert shift[1] == pytest.approx(target, rel=0.05)  # moves over the cycle; the lean lags it)
    assert np.array_equal(shift[[0, 2, 3, 5]], np.zeros(4))
    for g in (plain, lean):
        g.advance(env.step_phase, v, 0.0, 0.0, 0.0)
    assert abs(lean.lean_m) < abs(target)  # the turn is over: the lean fades over ~0.3 s, not at once
    assert abs(lean.lean_m) > 0.5 * abs(target)


def test_a_policy_keeps_the_turn_lean_it_was_trained_with(tmp_path, train_params):
    env = train_params().env
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42}')
    leaned = replace(env, commands=replace(env.commands, turn_lean=1.0))
    assert policy_env(tmp_path, leaned).commands.turn_lean is None  # trained without: none
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42, "turn_lean": 0.8, '
                                          '"turn_lean_time_constant_s": 0.5, "max_lean_tan": 0.2}')
    c = policy_env(tmp_path, env).commands
    assert (c.turn_lean, c.turn_lean_time_constant_s, c.max_lean_tan) == (0.8, 0.5, 0.2)


def test_a_steering_lead_holds_the_heading_near_the_pelvis_heading(env, tmp_path, train_params):
    """`heading_lead_deg`: the steered heading stays within the lead of where the pelvis faces (across
    the +-180 deg seam too), is the command itself when nearer, and is recorded with the policy."""
    lead = np.radians(20.0)
    assert lead_heading(np.radians(90.0), 0.0, lead) == pytest.approx(lead)
    assert lead_heading(np.radians(-90.0), 0.0, lead) == pytest.approx(-lead)
    assert lead_heading(np.radians(10.0), 0.0, lead) == pytest.approx(np.radians(10.0))
    assert lead_heading(np.radians(-170.0), np.radians(170.0), lead) == pytest.approx(np.radians(190.0))
    plain = GaitState(env.ref, replace(env.p.commands, heading_lead_deg=None))
    led = GaitState(env.ref, replace(env.p.commands, heading_lead_deg=20.0))
    v = env.ref.speed_mps
    for g in (plain, led):
        g.start(0.3, v, 0.0, 0.0)
        g.advance(env.step_phase, v, np.pi / 2, 0.0, 0.1)
    assert plain.heading == pytest.approx(np.pi / 2)  # off: the command as given
    assert led.heading == pytest.approx(0.1 + lead)
    assert np.array_equal(led.reference[0], plain.reference[0])  # the pose reference is unchanged
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42}')
    base = train_params().env
    with_lead = replace(base, commands=replace(base.commands, heading_lead_deg=25.0))
    assert policy_env(tmp_path, with_lead).commands.heading_lead_deg == 25.0  # none recorded: the params'
    (tmp_path / STEERING_FILE).write_text('{"stride_speed_exponent": 0.42, "heading_lead_deg": 15.0}')
    assert policy_env(tmp_path, with_lead).commands.heading_lead_deg == 15.0  # recorded: its own


def test_widened_policy_acts_like_the_straight_walker(train_params, camargo_model, cycle):
    """A 72-input policy with trained-looking normalisation statistics, widened to 74 inputs, gives
    the same actions on the observations it knew, whatever the new slots hold."""
    tp = replace(train_params(), net_arch=(32, 32), n_steps=64, batch_size=64)
    legacy_env = make_walk_env(camargo_model / "human.xml", cycle, tp.env)
    from gymnasium import spaces

    legacy_env.observation_space = spaces.Box(-np.inf, np.inf, (LEGACY_OBS_SIZE,), np.float32)
    rng = np.random.default_rng(1)
    old_norm = VecNormalize(DummyVecEnv([lambda: legacy_env]), norm_obs=True, norm_reward=False)
    old_norm.obs_rms.mean = rng.normal(size=LEGACY_OBS_SIZE)
    old_norm.obs_rms.var = rng.uniform(0.01, 2.0, LEGACY_OBS_SIZE)
    old_norm.obs_rms.var[list(UNTRAINED_SLOTS)] = 0.0  # constant in straight walking
    old = new_ppo(old_norm, tp)
    norm, model = widen_policy(old, old_norm, make_vec_env(camargo_model / "human.xml", cycle, tp, 1, False),
                               tp, cycle.speed_mps)
    norm.training = False
    for _ in range(20):
        obs = old_norm.obs_rms.mean + rng.normal(size=LEGACY_OBS_SIZE) * np.sqrt(old_norm.obs_rms.var) * 0.5
        obs[list(UNTRAINED_SLOTS)] = old_norm.obs_rms.mean[list(UNTRAINED_SLOTS)]
        for i in STEERING_STATS:
            if i < LEGACY_OBS_SIZE:  # stay inside both normalisations' clip range
                obs[i] = old_norm.obs_rms.mean[i] + 0.1 * np.sqrt(old_norm.obs_rms.var[i])
        new_obs = np.r_[obs, rng.normal(size=OBS_SIZE - LEGACY_OBS_SIZE)]
        new_obs[65] = cycle.speed_mps + rng.normal() * 0.3  # the commanded speed now varies
        a_old = old.predict(old_norm.normalize_obs(obs.astype(np.float32)), deterministic=True)[0]
        a_new = model.predict(norm.normalize_obs(new_obs.astype(np.float32)), deterministic=True)[0]
        assert np.allclose(a_old, a_new, atol=1e-4)
