"""Walking environment, AMP discriminator, training loop and policy human on the real camargo model
and reference cycle (the `scale` and `reference` stages' outputs)."""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

import sim.learn.train as train_module
from sim.body.human_params import joint_kind
from sim.errors import SimulationError
from sim.learn.amp import AMP, style_reward
from sim.learn.harness_twist import HarnessTwist, TwistParams
from sim.learn.policy_human import ActorMlp, PolicyHuman
from sim.learn.train import MetricsLog, load_body, load_policy, train
from sim.learn.walk_env import AMP_SIZE, OBS_SIZE, make_walk_env, motion_amp_features, motion_amp_pairs
from sim.motion.reference import load_reference, mirrored_motion
from sim.rollout.loop import RolloutParams, rollout
from sim.rollout.scenarios import Segment, command_profile


@pytest.fixture(scope="module")
def setup(params, camargo_model):
    tp, ev = params.train, params.evaluate_policy
    cycle = load_reference(camargo_model / "reference.npz").cycle
    return params, tp, ev, cycle


@pytest.fixture
def env(setup, camargo_model):
    _, tp, _, cycle = setup
    return make_walk_env(camargo_model / "human.xml", cycle, tp.env, seed=0)


def test_env_api_passes_gymnasium_checker(env):
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=1)
    assert obs.shape == (OBS_SIZE,) and np.isfinite(obs).all()
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert info["amp"].shape == (2 * AMP_SIZE,) and 0.0 <= reward <= 1.0


def test_servos_keep_the_literature_torque_limits(setup, env):
    params, _, _, _ = setup
    hp = params.human
    mass = float(env.model.body_mass.sum())
    for a in range(env.model.nu):
        kind = joint_kind(env.model.joint(env.model.actuator_trnid[a, 0]).name)
        assert env.model.actuator_forcerange[a, 1] == pytest.approx(hp.torque_limit_nm_per_kg[kind] * mass,
                                                                     rel=0.01)
        assert env.model.actuator_gainprm[a, 0] == env.p.pd_kp_nm_per_rad[kind]


def test_reference_state_init_and_imitation_reward(env, setup):
    _, _, _, cycle = setup
    walking = command_profile("steady", [Segment(walk_s=5.0)], cycle.speed_mps, 1 / env.dt)
    env.reset(seed=0, options={"phase": 0.5, "pushes": False, "commands": walking})
    k = int(0.5 * len(cycle.phase))
    assert np.allclose(env.data.qpos[2:], cycle.qpos[k, 2:]) and np.allclose(env.data.qpos[:2], 0)
    assert np.allclose(env.data.qvel, cycle.qvel[k])
    reward, terms = env._reward()
    assert terms[0] > 0.999 and terms[2] > 0.999 and terms[3] > 0.999  # pose, feet, height on the reference
    knee = env.model.joint("knee_r").qposadr[0]
    env.data.qpos[knee] += 0.6
    mujoco.mj_forward(env.model, env.data)
    worse, terms_off = env._reward()
    assert terms_off[0] < 0.6 and worse < reward


def test_early_termination_on_a_fall(env):
    env.reset(seed=0, options={"pushes": False})
    assert not env.fallen()
    env.data.qpos[2] = 0.3
    mujoco.mj_forward(env.model, env.data)
    assert env.fallen()
    _, reward, terminated, truncated, _ = env.step(np.zeros(21))
    assert terminated and not truncated and reward == 0.0


def test_random_pushes_act_on_the_pelvis(setup, camargo_model):
    _, tp, _, cycle = setup
    p = replace(tp.env, push_probability=1.0, push_force_n=(100.0, 100.0), push_interval_s=(0.05, 0.05),
                push_duration_s=0.1)
    env = make_walk_env(camargo_model / "human.xml", cycle, p, seed=3)
    env.reset(seed=3)
    seen = []
    for _ in range(8):
        env.step(np.zeros(21))
        seen.append(np.linalg.norm(env.data.xfrc_applied[env.idx.pelvis, :2]))
    assert max(seen) == pytest.approx(100.0) and min(seen) == 0.0


def test_harness_twist_resists_a_turn_within_the_harness_range():
    """A pelvis turning at 1 rad/s leaves the virtual base heading behind: the torque opposes the
    turn, the twist settles near rate x lag, never exceeds the range, and fades once the turn ends."""
    p = TwistParams(probability=1.0, stiffness_nm_per_rad=40.0, damping_nms_per_rad=3.0, range_rad=0.7)
    tw, dt = HarnessTwist(p, lag_s=0.4), 0.03
    tw.reset(0.0)
    yaw, torques = 0.0, []
    for _ in range(100):                       # 3 s turning left at 1 rad/s
        yaw += dt
        torques.append(tw.torque(yaw, dt))
    assert max(torques) < 0.0                  # resists the turn throughout
    assert tw.twist == pytest.approx(0.4, rel=0.1) and abs(tw.twist) <= p.range_rad
    fast = HarnessTwist(p, lag_s=5.0)
    fast.reset(0.0)
    for i in range(100):
        fast.torque(3.0 * dt * (i + 1), dt)
    assert abs(fast.twist) == pytest.approx(p.range_rad)  # the base is dragged along at the range
    for _ in range(200):                       # the turn ends: the base heading catches up
        last = tw.torque(yaw, dt)
    assert abs(last) < 0.01


def test_harness_twist_acts_on_the_pelvis_only_when_drawn(setup, camargo_model):
    _, tp, _, cycle = setup
    on = replace(tp.env, push_probability=0.0, harness_twist=replace(tp.env.harness_twist, probability=1.0))
    for p, expect in ((on, True), (tp.env, False)):
        env = make_walk_env(camargo_model / "human.xml", cycle, p, seed=4)
        env.reset(seed=4)
        torques = []
        for _ in range(15):
            env.step(np.zeros(21))
            torques.append(env.data.xfrc_applied[env.idx.pelvis, 5])
        assert (env.twist is not None) == expect
        assert (max(np.abs(torques)) > 0.0) == expect


def test_discriminator_separates_reference_from_other_motion(env, setup):
    _, tp, _, _ = setup
    rng = np.random.default_rng(0)
    amp = AMP(2 * AMP_SIZE, replace(tp.amp, hidden=(64, 64), epochs=2, learning_rate=1e-3),
              lambda n: env.ref.amp_pairs(rng, n, env.step_phase))
    fake = env.ref.amp_pairs(rng, 1024, env.step_phase)
    fake[:, 13:34] += 0.3  # joints offset by 0.3 rad: not the subject's motion
    fake[:, AMP_SIZE + 13:AMP_SIZE + 34] += 0.3
    for _ in range(20):  # the reference mixes standing, blends and walking (AMP_LEVELS)
        stats = amp.update(fake)
    assert stats["disc_acc_reference"] > 0.9 and stats["disc_acc_policy"] > 0.9
    real = env.ref.amp_pairs(rng, 512, env.step_phase)
    assert amp.reward(real).mean() > amp.reward(fake[:512]).mean() + 0.3
    assert float(style_reward(torch.tensor(1.0))) == 1.0 and float(style_reward(torch.tensor(-1.0))) == 0.0


def test_mirror_image_of_the_cycle_is_its_other_half(env, setup):
    """Reflected left-right, a stride of the right leg is the left leg's half a cycle later; twice is none."""
    _, _, _, cycle = setup
    q, v = mirrored_motion(env.model, cycle.qpos, cycle.qvel)
    q2, v2 = mirrored_motion(env.model, q, v)
    np.testing.assert_allclose(q2, cycle.qpos)
    np.testing.assert_allclose(v2, cycle.qvel)
    f, g = motion_amp_features(env.model, cycle.qpos, cycle.qvel), motion_amp_features(env.model, q, v)
    half = np.roll(f, -len(f) // 2, axis=0)
    sd = f.std(0) + 1e-6
    mirrored_err, plain_err = np.abs(g - half).mean(0) / sd, np.abs(f - half).mean(0) / sd
    moving = f.std(0) > 1e-3
    # the cycle's own left-right asymmetry remains; without the reflection the halves differ far more
    assert mirrored_err[moving].mean() < 0.5 * plain_err[moving].mean()
    assert np.mean(g[:, 8] * f[:, 8]) < 0  # root lateral velocity flips


def test_recorded_motion_gives_turning_reference_transitions(env, camargo_model):
    """Camargo's recording turns (a circuit): its transitions hold yaw rates the straight cycle lacks,
    each pair is the frame and the frame dt later, and a share of the reference is drawn from them."""
    ref = load_reference(camargo_model / "reference.npz")
    pairs = motion_amp_pairs(env.model, ref.time_s, ref.qpos, ref.qvel, ref.trial, env.dt,
                             ref.cycle.floor_shift_m)
    rate = ref.rate_hz(str(ref.trial[0]))
    lag = int(round(env.dt * rate))
    assert abs(env.dt * rate - lag) < 1e-6 and len(pairs) == len(ref.time_s) - lag
    np.testing.assert_allclose(pairs[:-lag, AMP_SIZE:], pairs[lag:, :AMP_SIZE], atol=1e-9)
    cycle_pairs = env.ref.amp_pairs(np.random.default_rng(0), 4000, env.step_phase)
    yaw_rate = 12  # root angular velocity z in the features
    peak = [np.quantile(np.abs(x[:, yaw_rate]), 0.95) for x in (pairs, cycle_pairs)]
    assert peak[0] > 1.5 * peak[1]
    mixed = env.ref.amp_pairs(np.random.default_rng(1), 4000, env.step_phase, pairs, 0.3)
    recorded = {row.tobytes() for row in pairs}
    from_motion = np.mean([row.tobytes() in recorded for row in mixed])
    assert 0.25 < from_motion < 0.35


def test_turn_imitation_scale_weakens_imitation_only_in_turns(setup, camargo_model):
    _, tp, _, cycle = setup
    rewards = []
    for scale in (1.0, 0.5):
        e = make_walk_env(camargo_model / "human.xml", cycle, replace(tp.env, turn_imitation_scale=scale),
                          seed=0)
        e.reset(seed=3, options={"pushes": False})
        e.gait.yaw_rate = 0.0
        straight, _ = e._reward()
        e.gait.yaw_rate = 1.0
        turning, terms = e._reward()
        rewards.append((straight, turning, terms))
    (s1, t1, terms), (s2, t2, _) = rewards
    assert s1 == s2  # walking straight: unchanged
    task = tp.env.w_task * terms[5]
    assert t2 - task == pytest.approx(0.5 * (t1 - task))


def test_short_training_run_checkpoints_and_resumes(tmp_path, setup, camargo_model):
    _, tp, _, cycle = setup
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32),
                amp=replace(tp.amp, hidden=(32, 32)))
    xml = camargo_model / "human.xml"
    rec = train(xml, cycle, p, tmp_path, n_envs=2, threads=1, total_steps=512, progress=False)
    assert rec["steps"] >= 512
    for name in ("policy.zip", "vecnormalize.pkl", "amp.pt", "progress.json"):
        assert (tmp_path / name).exists()
    rec2 = train(xml, cycle, p, tmp_path, n_envs=2, threads=1, total_steps=1024, resume=True,
                 progress=False)
    assert rec2["steps"] >= 1024 and len(rec2["runs"]) == 2
    logged = tmp_path / "dvclive" / "metrics.json"
    metrics = json.loads(logged.read_text())["train"] if logged.exists() else None
    if metrics is None:  # dvclive not installed: CSV
        assert (tmp_path / "metrics.csv").read_text().count("\n") >= 2
    else:
        assert {"disc_acc_reference", "style_reward", "r_pose"} <= set(metrics)


def test_ctrl_c_stops_single_body_training_with_a_checkpoint(tmp_path, setup, camargo_model, monkeypatch):
    """SIGINT mid-run (sent by the run's own budget callback at 300 steps, so the step is known):
    the single-body trainer saves its policy and record at that step, then raises KeyboardInterrupt
    as Ctrl-C would, its earlier handler back."""
    _, tp, _, cycle = setup
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32), checkpoint_steps=256,
                amp=replace(tp.amp, hidden=(32, 32)))

    class SignalAt300(train_module.Budget):
        def _on_step(self) -> bool:
            if self.num_timesteps == 300:
                os.kill(os.getpid(), signal.SIGINT)
            return super()._on_step()

    monkeypatch.setattr(train_module, "Budget", SignalAt300)
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        train(camargo_model / "human.xml", cycle, p, tmp_path, n_envs=2, threads=1, total_steps=1024,
              progress=False)
    rec = json.loads((tmp_path / "progress.json").read_text())
    assert rec["steps"] == 300 and load_policy(tmp_path)[0].num_timesteps == 300
    assert signal.getsignal(signal.SIGINT) is before


def test_a_raising_training_gives_ctrl_c_back_and_ends_its_envs(tmp_path, setup, camargo_model, monkeypatch,
                                                             failing_budget):
    """An error mid-run (raised by the run's budget callback at 300 steps) reaches the caller, the
    SIGINT and SIGTERM handlers from before training are back (SB3 calls no end hook on an error,
    and a notebook's Ctrl-C would otherwise only set a flag no one reads) and the env processes ended."""
    _, tp, _, cycle = setup
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32), checkpoint_steps=256,
                amp=replace(tp.amp, hidden=(32, 32)))

    monkeypatch.setattr(train_module, "Budget", failing_budget)
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    children = set(multiprocessing.active_children())
    with pytest.raises(RuntimeError, match="a failing callback"):
        train(camargo_model / "human.xml", cycle, p, tmp_path, n_envs=2, threads=1, total_steps=1024,
              progress=False, subprocess=True)
    assert {s: signal.getsignal(s) for s in before} == before
    assert set(multiprocessing.active_children()) == children


def test_metrics_without_dvclive_keep_each_callers_names(tmp_path):
    log = MetricsLog(tmp_path, resume=False)
    log.live = None  # as on a machine without dvclive
    log(128, {"style_reward": 0.5, "episode_length": 200.0})
    log(128, {"ppo_approx_kl": 0.01})  # another callback, other names, the same step
    rows = (tmp_path / "metrics.csv").read_text().splitlines()
    assert rows == ["step,metric,value", "128,style_reward,0.5", "128,episode_length,200",
                    "128,ppo_approx_kl,0.01"]


@pytest.mark.parametrize("subject", ["camargo", "opencap4"])
def test_committed_policy_walks_through_the_rollout_engine(setup, policies_root, subject):
    """Each example subject's committed policy walks 3 s on the body it was trained on."""
    params, tp, _, _ = setup
    folder = policies_root / subject
    model, norm = load_policy(folder)
    body, cycle = load_body(folder)  # the body the policy was trained on
    env = make_walk_env(body, cycle, tp.env)

    def policy(obs):
        return model.predict(norm.normalize_obs(obs), deterministic=True)[0]

    human = PolicyHuman(policy, env.ref, cycle, tp.env, 3.0, start_phase=0.3)
    p = RolloutParams(robot=params.robot.build(), sample_rate_hz=100.0, with_robot=False)
    result = rollout(mujoco.MjSpec.from_file(str(body)), human, None, p, 0)
    assert result.stable and human.fall_time_s is None
    assert result.human_qpos.shape == (301, env.model.nq)
    speed = (result.human_qpos[-1, 0] - result.human_qpos[0, 0]) / 3.0
    assert speed == pytest.approx(cycle.speed_mps, rel=0.15)


def test_numpy_actor_gives_the_trained_policys_actions(setup, policies_root):
    """`ActorMlp` (the rollouts' forward pass) returns stable-baselines3's deterministic action for
    the same observation, normaliser included, up to float32 summation order."""
    _, tp, _, _ = setup
    model, norm = load_policy(policies_root / "camargo")
    actor = ActorMlp.from_sb3(model, norm)
    body, cycle = load_body(policies_root / "camargo")
    env = make_walk_env(body, cycle, tp.env)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(20):
        expected = model.predict(norm.normalize_obs(obs), deterministic=True)[0]
        action = actor(obs)
        assert action.dtype == np.float32
        np.testing.assert_allclose(action, expected, atol=2e-6)
        obs, *_ = env.step(expected + rng.normal(0.0, 0.05, expected.shape))
    far = obs * 0 + 1e6  # clipped by the normaliser, then clipped actions
    np.testing.assert_allclose(actor(far), model.predict(norm.normalize_obs(far), deterministic=True)[0],
                               atol=2e-6)


def test_training_can_start_from_another_subjects_policy(tmp_path, setup, camargo_model, policies_root):
    """`init_from`: the new run starts from the given policy, normaliser and discriminator (same
    observation / action layout for every subject) and counts its own steps from zero."""
    _, tp, _, cycle = setup
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32),
                amp=replace(tp.amp, hidden=(32, 32)))
    xml = camargo_model / "human.xml"
    first = train(xml, cycle, p, tmp_path / "a", n_envs=2, threads=1, total_steps=512, progress=False)
    rec = train(xml, cycle, p, tmp_path / "b", n_envs=2, threads=1, total_steps=256, progress=False,
                init_from=tmp_path / "a")
    assert rec["initialised_from"].endswith(str(Path("a")))
    assert rec["initial_policy_steps"] == first["steps"]
    assert 256 <= rec["steps"] < first["steps"] + 256 and len(rec["runs"]) == 1
    (a, norm_a), (b, norm_b) = load_policy(tmp_path / "a"), load_policy(tmp_path / "b")
    wa, wb = (m.policy.mlp_extractor.policy_net[0].weight.detach().numpy() for m in (a, b))
    assert np.abs(wb - wa).mean() < 0.05 * np.abs(wa).mean()  # a few updates away from a
    assert norm_b.obs_rms.count > norm_a.obs_rms.count  # the observation statistics carried over
    assert (b.learning_rate, b.gamma) == (p.learning_rate, p.gamma)
    # a fine-tune runs with its own PPO settings, not the ones saved with its start
    tuned = replace(p, learning_rate=p.learning_rate / 4, gamma=0.9, n_epochs=2)
    train(xml, cycle, tuned, tmp_path / "d", n_envs=2, threads=1, total_steps=256, progress=False,
          init_from=tmp_path / "a")
    d, _ = load_policy(tmp_path / "d")
    assert (d.learning_rate, d.gamma, d.n_epochs) == (p.learning_rate / 4, 0.9, 2)
    with pytest.raises(FileNotFoundError, match="no policy to start from"):
        train(xml, cycle, p, tmp_path / "c", n_envs=2, threads=1, total_steps=256, progress=False,
              init_from=tmp_path / "missing")
    body_conditioned = policies_root / "kgc6"  # an export of the universal policy: 81 observations
    with pytest.raises(SimulationError, match="policy of 81 observations.*fine-tuned by `transfer`"):
        train(xml, cycle, p, tmp_path / "e", n_envs=2, threads=1, total_steps=256, progress=False,
              init_from=body_conditioned)


def test_real_gait_in_the_model_matches_the_dataset_curves(params, camargo_model):
    """The SPM reference of evaluate-policy: camargo's free walking retargeted onto its model and
    processed like a simulation gives about as many cycles as the real recording, close to the
    dataset's own IK curves (the residual is the model's joint definitions and its virtual markers)."""
    import pandas as pd

    from ingest.subject import load_subject
    from metrics.policy_checks import curves, spm_check
    from sim.rollout.batch import reference_cycles

    model = mujoco.MjModel.from_xml_path(str(camargo_model / "human.xml"))
    cycles = reference_cycles(model, load_reference(camargo_model / "reference.npz"), "camargo",
                              load_subject("camargo").markerset, params.ingest)
    real = pd.read_parquet(camargo_model.parent / "real" / "cycles.parquet")
    real = real[real["condition"] == "free"]
    for joint in ("hip_flexion", "knee_flexion"):
        a, b = curves(real, joint), curves(cycles, joint)
        assert abs(len(b) - len(a)) <= 2
        assert np.abs(a.mean(0) - b.mean(0)).mean() < 2.5
        same = spm_check(b, b + np.random.default_rng(0).normal(0, 0.5, b.shape))
        assert same["longest_cluster_pct"] < 20 and same["pass"]
        shifted = spm_check(b, b + 15.0)  # a 15-degree offset is significant over the whole cycle
        assert shifted["longest_cluster_pct"] > 90 and not shifted["pass"]


def test_policy_human_refuses_a_world_at_another_timestep(setup, policies_root):
    """The policy's PD servos were trained at the body's 2 ms step: 200 Hz samples would make the
    world step 1.67 ms, which the policy human refuses rather than walk (and fall) there."""
    params, tp, _, _ = setup
    body, cycle = load_body(policies_root / "camargo")
    env = make_walk_env(body, cycle, tp.env)
    human = PolicyHuman(lambda obs: np.zeros(21), env.ref, cycle, tp.env, 1.0)
    p = RolloutParams(robot=params.robot.build(), sample_rate_hz=200.0, with_robot=False)
    with pytest.raises(SimulationError, match="trained at 2.000 ms"):
        rollout(mujoco.MjSpec.from_file(str(body)), human, None, p, 0)


def test_training_runs_as_a_ray_job_and_resumes(tmp_path, setup, camargo_model):
    """`train_on_ray`: the same training as one Ray job; the folder comes back and resumes there."""
    from sim.learn.train_ray import train_on_ray

    _, tp, _, cycle = setup
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32),
                amp=replace(tp.amp, hidden=(32, 32)))
    xml = camargo_model / "human.xml"
    rec = train_on_ray(xml, cycle, p, tmp_path, cpus=1, n_envs=2, threads=1, total_steps=256)
    assert rec["steps"] >= 256 and (tmp_path / "policy.zip").is_file()
    assert json.loads((tmp_path / "progress.json").read_text())["steps"] == rec["steps"]
    again = train_on_ray(xml, cycle, p, tmp_path, cpus=1, n_envs=2, threads=1, total_steps=512, resume=True)
    assert again["steps"] >= 512 and len(again["runs"]) == 2


def test_longer_swing_warps_the_cycle_without_changing_stride_or_speed(setup, camargo_model):
    """A hemiparetic variant's reference (`with_longer_swing`): the named foot swings longer than
    the other by about the ratio asked, while period, stride and mean speed stay the subject's, and
    the velocities stay the derivative of the warped positions (the chain rule)."""
    from sim.motion.reference import foot_forward_m, swing_mask, with_longer_swing

    _, _, _, cycle = setup
    model = mujoco.MjModel.from_xml_path(str(camargo_model / "human.xml"))
    warped = with_longer_swing(model, cycle, "left", 1.25)

    def shares(c):
        return [float(swing_mask(c, foot_forward_m(model, c.qpos, s)).mean()) for s in ("left", "right")]

    (l0, r0), (l1, r1) = shares(cycle), shares(warped)
    assert abs(l0 / r0 - 1.0) < 0.05                 # the subject walks symmetrically
    assert l1 / r1 > 1.12 and l1 > l0 and r1 < r0    # the left swing got longer, the right shorter
    assert warped.period_s == cycle.period_s and warped.stride_length_m == cycle.stride_length_m
    assert np.mean(warped.qvel[:, 0]) == pytest.approx(np.mean(cycle.qvel[:, 0]), rel=0.02)
    n = len(cycle.phase)
    knee = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knee_l")]
    knee_v = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knee_l")]
    diff = (np.roll(warped.qpos[:, knee], -1) - np.roll(warped.qpos[:, knee], 1)) / (2 * cycle.period_s / n)
    assert np.corrcoef(diff, warped.qvel[:, knee_v])[0, 1] > 0.95
    quats = warped.qpos[:, 3:7]
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0)


def test_a_hemiparetic_variant_trains_on_and_keeps_its_asymmetric_cycle(tmp_path, setup, camargo_model,
                                                                       train_params):
    """Training a variant with `swing_time_ratio` imitates the warped cycle and saves it beside the
    policy, so its rollouts (which load the policy's own cycle) walk the same reference; a resume
    warps the subject's cycle again to the same one."""
    from sim.motion.reference import foot_forward_m, swing_mask

    _, _, _, cycle = setup
    tp = train_params("hemiparetic_right")
    p = replace(tp, n_steps=128, batch_size=256, n_epochs=1, net_arch=(32, 32),
                amp=replace(tp.amp, hidden=(32, 32)))
    xml = camargo_model / "human.xml"
    train(xml, cycle, p, tmp_path, n_envs=2, threads=1, total_steps=256, progress=False)
    _, saved = load_body(tmp_path)
    model = mujoco.MjModel.from_xml_path(str(xml))
    left, right = (swing_mask(saved, foot_forward_m(model, saved.qpos, s)).mean() for s in ("left", "right"))
    assert right / left > 1.2
    train(xml, cycle, p, tmp_path, n_envs=2, threads=1, total_steps=512, resume=True, progress=False)
    np.testing.assert_array_equal(load_body(tmp_path)[1].qpos, saved.qpos)


def test_a_variant_is_fine_tuned_under_its_training_noise_and_walks_with_its_own(setup, camargo_model):
    """`train_action_noise` is the noise of the training env; `action_noise` is what its rollouts
    walk with (`PolicyHuman.action_noise`), and the training env uses it only when no training
    noise is set."""
    from sim.body.variant import Variant

    _, tp, _, cycle = setup

    def ctrl_after_a_step(variant: Variant) -> np.ndarray:
        env = make_walk_env(camargo_model / "human.xml", cycle, replace(tp.env, variant=variant), seed=0)
        env.reset(seed=3)
        env.step(np.zeros(env.action_space.shape))
        return env.data.ctrl.copy()

    quiet = ctrl_after_a_step(Variant())
    np.testing.assert_array_equal(ctrl_after_a_step(Variant(action_noise=0.3, train_action_noise=0.0)), quiet)
    assert np.abs(ctrl_after_a_step(Variant(train_action_noise=0.3)) - quiet).max() > 1e-3
    assert np.abs(ctrl_after_a_step(Variant(action_noise=0.3)) - quiet).max() > 1e-3
    assert Variant(action_noise=0.08, train_action_noise=0.15).training_noise == 0.15
    assert Variant(action_noise=0.08).training_noise == 0.08
