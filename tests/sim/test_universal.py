"""Bodies around a subject's and the body-conditioned walking policy (sim/learn/bodies.py,
sim/learn/universal.py) on camargo's real scaled human and reference cycle."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import re
import shutil
import signal
from dataclasses import replace

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import sim.learn.universal as universal_module
from sim.learn.bodies import (
    BODY_OBS_SIZE,
    BODY_OBS_SIZES,
    BodyDraw,
    BodyScales,
    body_observation,
    draw_scales,
    leg_length,
    scale_spec,
    similar_cycle,
)
from sim.learn.pool import UNIVERSAL_OBS_SIZE, MultiBodyEnv, Source, UniversalParams, make_body
from sim.learn.steering import geom_bottom, subtree
from sim.learn.train import load_norm, load_policy, new_ppo
from sim.learn.universal import (
    ActionBound,
    beyond_bound,
    hidden_sizes,
    load_teachers,
    params_from_yaml,
    pool_observations,
    progress_text,
    restat,
    rewind,
    rewound,
    train_universal,
    widen_for_body,
    widen_layers,
)
from sim.learn.walk_env import OBS_SIZE, make_walk_env
from sim.motion.reference import load_reference
from sim.rollout.scenarios import PHASES


@pytest.fixture(scope="module")
def camargo(camargo_model):
    xml = str(camargo_model / "human.xml")
    return Source("camargo", xml, str(camargo_model / "reference.npz")), mujoco.MjModel.from_xml_path(xml), \
        load_reference(camargo_model / "reference.npz").cycle


def _scaled(xml: str, s: BodyScales) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(xml)
    scale_spec(spec, s)
    return spec.compile()


def test_a_geometric_scaling_scales_lengths_masses_and_torques(camargo):
    src, model, _ = camargo
    big = _scaled(src.xml, BodyScales.uniform(1.1, 1.1 ** 3))
    assert leg_length(big) == pytest.approx(1.1 * leg_length(model), rel=1e-9)
    assert big.body_mass.sum() == pytest.approx(1.1 ** 3 * model.body_mass.sum(), rel=1e-9)
    np.testing.assert_allclose(big.actuator_gear[:, :3], model.actuator_gear[:, :3] * 1.1 ** 4, rtol=1e-9)
    foot = model.body("foot_l").id
    np.testing.assert_allclose(big.body_inertia[foot], model.body_inertia[foot] * 1.1 ** 5, rtol=1e-9)


def test_drawn_bodies_stay_within_the_range(camargo):
    rng = np.random.default_rng(0)
    draws = [draw_scales(rng, BodyDraw(range=0.15, segment_jitter=0.05)) for _ in range(200)]
    lengths, masses = np.array([d.length for d in draws]), np.array([d.mass for d in draws])
    assert lengths.min() >= 0.85 - 1e-12 and lengths.max() <= 1.15 + 1e-12
    assert masses.min() >= 0.85 - 1e-12 and masses.max() <= 1.15 + 1e-12
    assert lengths.std() > 0.05  # they do differ


def test_the_cycle_carries_over_by_dynamic_similarity(camargo):
    src, model, cycle = camargo
    big = _scaled(src.xml, BodyScales.uniform(1.1, 1.1 ** 3))
    c = similar_cycle(model, big, cycle)
    assert c.speed_mps == pytest.approx(cycle.speed_mps * math.sqrt(1.1), rel=1e-9)
    assert c.period_s == pytest.approx(cycle.period_s * math.sqrt(1.1), rel=1e-9)
    assert c.stride_length_m == pytest.approx(cycle.stride_length_m * 1.1, rel=1e-9)
    np.testing.assert_array_equal(c.qpos[:, 7:], cycle.qpos[:, 7:])  # the same joint angles
    feet = [model.body(f"foot_{s}").id for s in "lr"]
    for m, q in ((model, cycle.qpos), (big, c.qpos)):
        d = mujoco.MjData(m)
        geoms = np.flatnonzero(np.isin(m.geom_bodyid, subtree(m, np.array(feet))))
        lows = []
        for k in range(0, len(q), 10):
            d.qpos[:] = q[k]
            mujoco.mj_kinematics(m, d)
            lows.append(min(geom_bottom(m, d, g) for g in geoms))
        if m is model:
            ref_lows = lows
    np.testing.assert_allclose(lows, ref_lows, atol=1e-9)  # feet clear the floor as on the source body


def test_the_body_observation_reads_the_body(camargo):
    src, model, cycle = camargo
    big = _scaled(src.xml, BodyScales.uniform(1.1, 1.2))
    a, b = body_observation(model, cycle), body_observation(big, similar_cycle(model, big, cycle))
    assert a.shape == (BODY_OBS_SIZE,)
    np.testing.assert_allclose(b - a, [math.log(1.1), math.log(1.2), math.log(1.1), 0.5 * math.log(1.1),
                                       0.5 * math.log(1.1), 0.0, 0.0], atol=0.01)  # balance: per leg length


@pytest.fixture(scope="module")
def universal(params, camargo):
    p, up, scenarios = params_from_yaml(params._path)
    up = replace(up, subjects=("camargo",), drawn=2, gate_seeds=1, gate_scenarios=("walk_10m",),
                 critic_warmup_steps=256, teachers=(), net_arch=None,
                 learning_rate=None)  # the tests set PPO's rate through `p`, whatever params.yaml's run uses
    return p, up, scenarios


def test_a_pool_of_bodies_is_one_gymnasium_env(universal, camargo):
    p, up, _ = universal
    env = MultiBodyEnv((camargo[0],), up, p.env, seed=0)
    check_env(env, skip_render_check=True)
    seen = set()
    for i in range(12):
        obs, _ = env.reset(seed=i)
        assert obs.shape == (UNIVERSAL_OBS_SIZE,) and np.isfinite(obs).all()
        seen.add(tuple(np.round(obs[OBS_SIZE:], 6)))
    assert len(seen) == 3  # camargo's own body and the two drawn ones


def test_widening_keeps_the_single_body_policy(universal, camargo, tmp_path):
    p, up, _ = universal
    src, _, cycle = camargo
    single = DummyVecEnv([lambda: make_walk_env(src.xml, cycle, p.env, seed=0)])
    norm = VecNormalize(single, norm_obs=True, norm_reward=False)
    old = new_ppo(norm, replace(p, net_arch=(32, 32)))
    norm.obs_rms.mean = np.random.default_rng(1).normal(size=OBS_SIZE)
    multi = DummyVecEnv([lambda: MultiBodyEnv((src,), up, p.env, seed=0)])
    wide_norm, wide = widen_for_body(old, norm, multi, replace(p, net_arch=(32, 32)), np.zeros(BODY_OBS_SIZE),
                                     np.full(BODY_OBS_SIZE, 0.1))
    assert not wide_norm.training  # the statistics the old policy knows stay as they are
    rng = np.random.default_rng(2)
    for _ in range(5):
        obs = rng.normal(size=OBS_SIZE).astype(np.float32)
        body = rng.normal(scale=0.2, size=BODY_OBS_SIZE).astype(np.float32)
        a_old, _ = old.predict(norm.normalize_obs(obs[None]), deterministic=True)
        x = wide_norm.normalize_obs(np.concatenate([obs, body])[None])
        a_new, _ = wide.predict(x, deterministic=True)
        np.testing.assert_allclose(a_new, a_old, atol=1e-6)


def test_widened_layers_act_and_value_as_before(universal, camargo):
    p, up, _ = universal
    p = replace(p, net_arch=(32, 32))
    venv = VecNormalize(DummyVecEnv([lambda: MultiBodyEnv((camargo[0],), up, p.env, seed=0)]), norm_obs=False)
    old = new_ppo(venv, p)
    x = torch.as_tensor(np.random.default_rng(3).normal(size=(64, UNIVERSAL_OBS_SIZE)), dtype=torch.float32)
    old.policy.optimizer.zero_grad()
    values, log_prob, _ = old.policy.evaluate_actions(x, torch.zeros((64, 21)))
    (values.mean() + log_prob.mean()).backward()
    old.policy.optimizer.step()  # Adam's moments to carry over
    wide = widen_layers(old, venv, p, (48, 40))
    assert hidden_sizes(wide) == (48, 40) and wide.num_timesteps == old.num_timesteps
    with torch.no_grad():
        mean = [m.policy.get_distribution(x).distribution.mean for m in (old, wide)]
        values = [m.policy.predict_values(x) for m in (old, wide)]
    for a, b in (mean, values):
        np.testing.assert_allclose(b.numpy(), a.numpy(), atol=1e-5)
    first_old, first_wide = (m.policy.mlp_extractor.policy_net[0].weight.detach().abs() for m in (old, wide))
    assert first_wide[32:].mean() < 0.3 * first_old.mean()  # added units start small: ADDED_UNIT_SCALE
    i = [n for n, _ in wide.policy.named_parameters()].index("mlp_extractor.policy_net.0.weight")
    moments = wide.policy.optimizer.state_dict()["state"][i]
    first = moments["exp_avg_sq"]  # the policy network's first layer: 32 of its 48 units carried over
    assert first.shape == (48, UNIVERSAL_OBS_SIZE)
    np.testing.assert_array_equal(first[:32], old.policy.optimizer.state_dict()["state"][i]["exp_avg_sq"])
    assert torch.all(first[32:] > 0) and torch.all(moments["exp_avg"][32:] == 0)
    with pytest.raises(ValueError, match="can only be widened"):
        widen_layers(old, venv, p, (16, 32))


def test_re_estimated_statistics_keep_what_the_networks_do(universal, camargo):
    """`restat`: the statistics become the sample's, and the policy and value networks give the same
    outputs for observations inside both clip ranges; Adam's moments follow the weights' scale; an
    observation with an input past the old clip is counted."""
    p, up, _ = universal
    p = replace(p, net_arch=(32, 32))
    venv = VecNormalize(DummyVecEnv([lambda: MultiBodyEnv((camargo[0],), up, p.env, seed=0)]), norm_obs=True,
                        norm_reward=False, clip_obs=10.0)
    venv.training = False
    model = new_ppo(venv, p)
    raw = pool_observations(model, venv, 24)
    assert raw.shape == (24, UNIVERSAL_OBS_SIZE) and np.isfinite(raw).all()
    rng = np.random.default_rng(4)
    venv.obs_rms.mean = rng.normal(size=UNIVERSAL_OBS_SIZE)
    venv.obs_rms.var = rng.uniform(0.5, 2.0, UNIVERSAL_OBS_SIZE)
    x = torch.as_tensor(rng.normal(size=(64, UNIVERSAL_OBS_SIZE)), dtype=torch.float32)
    model.policy.optimizer.zero_grad()
    values, log_prob, _ = model.policy.evaluate_actions(x, torch.zeros((64, 21)))
    (values.mean() + log_prob.mean()).backward()
    model.policy.optimizer.step()  # Adam's moments to carry over
    i = [n for n, _ in model.policy.named_parameters()].index("mlp_extractor.policy_net.0.weight")
    v_before = model.policy.optimizer.state_dict()["state"][i]["exp_avg_sq"].clone()
    scale = rng.uniform(0.5, 3.0, UNIVERSAL_OBS_SIZE)
    sample = rng.normal(size=(4000, UNIVERSAL_OBS_SIZE)) * scale + rng.normal(size=UNIVERSAL_OBS_SIZE)
    sample[0, 3] = venv.obs_rms.mean[3] + 30.0 * np.sqrt(venv.obs_rms.var[3])  # past the old clip
    z_old = np.abs(sample - venv.obs_rms.mean) / np.sqrt(venv.obs_rms.var + venv.epsilon)
    z_new = np.abs(sample - sample.mean(0)) / np.sqrt(sample.var(0) + venv.epsilon)
    probe = sample[(z_old <= 10).all(1) & (z_new <= 10).all(1)][:200]  # inside both clip ranges
    assert len(probe) == 200
    old_x = torch.as_tensor(venv.normalize_obs(probe), dtype=torch.float32)
    with torch.no_grad():
        before = (model.policy.get_distribution(old_x).distribution.mean, model.policy.predict_values(old_x))
    var_old = venv.obs_rms.var.copy()
    info = restat(model, venv, sample)
    np.testing.assert_allclose(venv.obs_rms.mean, sample.mean(0))
    np.testing.assert_allclose(venv.obs_rms.var, sample.var(0))
    assert info["samples"] == 4000 and info["clipped_before"] >= 1 / 4000
    new_x = torch.as_tensor(venv.normalize_obs(probe), dtype=torch.float32)
    with torch.no_grad():
        after = (model.policy.get_distribution(new_x).distribution.mean, model.policy.predict_values(new_x))
    for a, b in zip(before, after, strict=True):
        np.testing.assert_allclose(b.numpy(), a.numpy(), atol=1e-4)
    ratio = np.sqrt(sample.var(0) + venv.epsilon) / np.sqrt(var_old + venv.epsilon)  # per input
    v_after = model.policy.optimizer.state_dict()["state"][i]["exp_avg_sq"].numpy()
    np.testing.assert_allclose(v_after, v_before.numpy() / ratio ** 2, rtol=1e-5)


def test_one_run_resumes_and_records_its_gate(universal, camargo, tmp_path):
    p, up, scenarios = universal
    p = replace(p, n_steps=64, batch_size=128, n_epochs=1, checkpoint_steps=256, net_arch=(32, 32))
    # the first runs without a floor and with either leg's start, whatever params.yaml says
    p = replace(p, env=replace(p.env, commands=replace(p.env.commands, first_step="either")))
    up = replace(up, min_action_std=None, bound_weight=0.0)
    out = tmp_path / "universal"
    rec = train_universal((camargo[0],), p, up, out, scenarios, total_steps=256, n_envs=2)
    assert rec["steps"] == 256 and rec["obs_size"] == UNIVERSAL_OBS_SIZE
    gate = rec["checkpoints"][-1]
    assert gate["checks"] == 3 and set(gate["gate"]) == {"camargo"}
    for name, row in gate["gate"]["camargo"].items():  # a fall names where in the scenario it came
        if name.endswith("_no_fall"):
            assert len(row["fell_in"]) == row["value"] and set(row["fell_in"]) <= set(PHASES)
    seen = gate["training"]  # what training saw since the last checkpoint: every episode, PPO's updates
    assert "training" not in rec["checkpoints"][0] and seen["updates"] >= 1
    assert seen["ppo"]["epochs"] == 1 and seen["ppo"]["approx_kl"] >= 0 and seen["ppo"]["std"] > 0
    assert seen["episodes"] and set(seen["episodes"]) <= {"camargo", "drawn"}
    for n in seen["episodes"].values():
        assert 0 <= n["pushed_falls"] <= min(n["falls"], n["pushed"])
        assert max(n["falls"], n["pushed"]) <= n["episodes"]
        assert sum(n["calm_fell_in"].values()) == n["falls"] - n["pushed_falls"]
        assert set(n["calm_fell_in"]) <= set(PHASES)
    early = tmp_path / "early"
    shutil.copytree(out, early)
    again = train_universal((camargo[0],), p, up, out, scenarios, total_steps=512, n_envs=2, resume=True)
    assert again["steps"] == 512 and [c["steps"] for c in again["checkpoints"]] == [0, 256, 512]
    assert len(again["runs"]) == 2 and json.loads((out / "progress.json").read_text()) == again
    model, norm = load_policy(out)
    assert model.observation_space.shape == (UNIVERSAL_OBS_SIZE,)
    assert norm.obs_rms.mean.shape == (UNIVERSAL_OBS_SIZE,)
    assert load_norm(out).obs_rms.count > 0

    half = tmp_path / "half"  # a checkpoint without its discriminator: refused, the run untouched
    shutil.copytree(early, half)
    (half / "amp.pt").unlink()
    before = {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()}
    with pytest.raises(FileNotFoundError, match=re.escape(f"{half}: missing amp.pt")):
        rewind(out, half, "a test")
    assert {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()} == before
    back = rewind(out, early, "a test")  # the branch from 256 to 512 given up, kept in the record
    assert back["steps"] == 256 and load_policy(out)[0].num_timesteps == 256
    assert back["discarded"] == [{"from_steps": 256, "to_steps": 512, "why": "a test",
                                  "wall_s": round(again["wall_s"] - rec["wall_s"], 1),
                                  "runs": again["runs"][1:], "checkpoints": again["checkpoints"][2:]}]
    with pytest.raises(ValueError, match="not an earlier checkpoint of this run"):
        rewound(rec, again, "a later record is no earlier checkpoint")
    calmer = {"push_probability": 0.0, "push_force_n": (0.0, 100.0)}  # the training envs' own values
    left = replace(p, env=replace(p.env, commands=replace(p.env.commands, first_step="left")))
    wider = replace(up, net_arch=(48, 32), env=calmer, min_action_std=0.5, bound_weight=10.0,
                    learning_rate=1e-5)
    last = train_universal((camargo[0],), left, wider, out, scenarios, total_steps=512, n_envs=2, resume=True,
                           restat_steps=32)  # wider, no pushes, statistics re-estimated first
    assert [c["steps"] for c in last["checkpoints"]] == [0, 256, 512]
    assert last["discarded"] == back["discarded"]  # carried on by the resumed run
    assert last["widened"] == [{"steps": 256, "net_arch": [[32, 32], [48, 32]]}]
    assert [(s["steps"], s["samples"]) for s in last["statistics"]] == [(256, 32)]
    assert hidden_sizes(load_policy(out)[0]) == (48, 32)
    assert last["runs"][-1]["env"] == {"push_probability": 0.0, "push_force_n": [0.0, 100.0]}
    assert last["runs"][-1]["min_action_std"] == 0.5 and "min_action_std" not in last["runs"][0]
    assert last["runs"][-1]["first_step"] == "left" and "first_step" not in last["runs"][0]
    assert last["runs"][-1]["bound_weight"] == 10.0 and "bound_weight" not in last["runs"][0]
    assert last["runs"][-1]["learning_rate"] == 1e-5 and "learning_rate" not in last["runs"][0]
    assert load_policy(out)[0].learning_rate == 1e-5  # the run's own, not the saved policy's
    assert 0 <= last["checkpoints"][-1]["training"]["ppo"]["beyond_bound"] <= 1
    assert torch.exp(load_policy(out)[0].policy.log_std).min() >= 0.5 - 1e-6  # raised from exp(-1) = 0.37
    assert all(n["pushed"] == 0 for n in last["checkpoints"][-1]["training"]["episodes"].values())


def test_the_progress_record_keeps_a_line_per_checkpoint():
    gate = {"camargo": {"walk_10m_no_fall": {"value": 0, "pass": True, "fell_in": []}}}
    rec = {"steps": 512, "subjects": ["camargo"], "widened": [], "runs": [{"steps": 512, "wall_s": 1.5}],
           "checkpoints": [{"steps": s, "passed": 1, "gate": gate} for s in (0, 256, 512)]}
    text = progress_text(rec)
    assert json.loads(text) == rec and text.endswith("}\n")
    lines = [json.loads(line.strip().rstrip(",")) for line in text.splitlines() if line.startswith("  {")]
    assert lines == rec["runs"] + rec["checkpoints"]  # one line each, in order
    assert len(text) < 0.7 * len(json.dumps(rec, indent=1))


def test_a_signal_stops_the_run_with_a_checkpoint_then_acts(universal, camargo, tmp_path, monkeypatch):
    """SIGTERM during training (here sent by the run's own wall-time callback at 300 steps, so the
    step is known): the run stops at that step (the callbacks after it see the signal), saves its
    checkpoint and record there, and then exits as SIGTERM would (status 143), the earlier handler
    back."""
    p, up, scenarios = universal
    p = replace(p, n_steps=64, batch_size=128, n_epochs=1, checkpoint_steps=256, net_arch=(32, 32))
    up = replace(up, min_action_std=None, bound_weight=0.0)

    class SignalAt300(universal_module.Budget):
        def _on_step(self) -> bool:
            if self.num_timesteps == 300:
                os.kill(os.getpid(), signal.SIGTERM)
            return super()._on_step()

    monkeypatch.setattr(universal_module, "Budget", SignalAt300)
    before = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "universal"
    with pytest.raises(SystemExit) as stopped:
        train_universal((camargo[0],), p, up, out, scenarios, total_steps=1024, n_envs=2)
    assert stopped.value.code == 128 + signal.SIGTERM
    rec = json.loads((out / "progress.json").read_text())
    assert rec["steps"] == 300
    assert [c["steps"] for c in rec["checkpoints"]] == [0, 256, 300]
    assert load_policy(out)[0].num_timesteps == 300 and rec["runs"][-1]["steps"] == 300
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_raising_run_gives_the_signals_back_and_ends_its_envs(universal, camargo, tmp_path, monkeypatch,
                                                               failing_budget):
    """An error mid-run reaches the caller with the SIGINT and SIGTERM handlers from before the run
    back (SB3 calls no end hook on an error) and its env processes ended."""
    p, up, scenarios = universal
    p = replace(p, n_steps=64, batch_size=128, n_epochs=1, checkpoint_steps=256, net_arch=(32, 32))
    up = replace(up, min_action_std=None, bound_weight=0.0)

    monkeypatch.setattr(universal_module, "Budget", failing_budget)
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    children = set(multiprocessing.active_children())
    with pytest.raises(RuntimeError, match="a failing callback"):
        train_universal((camargo[0],), p, up, tmp_path / "universal", scenarios, total_steps=1024,
                        n_envs=2, gate=False, subprocess=True, workers=2)
    assert {s: signal.getsignal(s) for s in before} == before
    assert set(multiprocessing.active_children()) == children


class _FirstInputs(gym.ObservationWrapper):
    """A pool whose observation stops after the first `n` values (a run from before values were appended)."""

    def __init__(self, env: gym.Env, n: int) -> None:
        super().__init__(env)
        self.n, self.observation_space = n, gym.spaces.Box(-np.inf, np.inf, (n,), np.float32)

    def observation(self, obs):
        return obs[:self.n]


def test_a_run_resumed_after_body_values_were_appended_is_widened(universal, camargo, tmp_path):
    """A checkpoint trained on the first five body values resumes with zero weights on the appended
    ones (`BALANCE`): the same actions whatever they are, Adam's moments kept, `widened` recorded."""
    p, up, scenarios = universal
    p = replace(p, n_steps=64, batch_size=128, n_epochs=1, checkpoint_steps=256, net_arch=(32, 32))
    out, src = tmp_path / "universal", camargo[0]
    train_universal((src,), p, up, out, scenarios, total_steps=256, n_envs=2, gate=False)
    model, norm = load_policy(out)
    n_old = OBS_SIZE + BODY_OBS_SIZES[0]  # the checkpoint as a run from before BALANCE saved it
    narrow_norm = VecNormalize(DummyVecEnv([lambda: _FirstInputs(MultiBodyEnv((src,), up, p.env, 0), n_old)]),
                               norm_obs=True, norm_reward=False, clip_obs=10.0)
    narrow_norm.obs_rms.mean, narrow_norm.obs_rms.var = norm.obs_rms.mean[:n_old], norm.obs_rms.var[:n_old]
    narrow_norm.training = False
    narrow = new_ppo(narrow_norm, p)
    first = [f"mlp_extractor.{n}.0.weight" for n in ("policy_net", "value_net")]
    state = model.policy.state_dict()
    narrow.policy.load_state_dict({k: v[:, :n_old] if k in first else v for k, v in state.items()})
    opt, names = model.policy.optimizer.state_dict(), [n for n, _ in model.policy.named_parameters()]
    for k in first:
        moments = opt["state"][names.index(k)]
        for m in ("exp_avg", "exp_avg_sq"):
            moments[m] = moments[m][:, :n_old]
    narrow.policy.optimizer.load_state_dict(opt)
    narrow.num_timesteps = model.num_timesteps
    narrow.save(str(out / "policy.zip"))
    narrow_norm.save(str(out / "vecnormalize.pkl"))
    rec = json.loads((out / "progress.json").read_text())
    (out / "progress.json").write_text(json.dumps({**rec, "obs_size": n_old}))

    again = train_universal((src,), p, up, out, scenarios, total_steps=256, n_envs=2, resume=True, gate=False)
    assert again["obs_size"] == UNIVERSAL_OBS_SIZE and again["widened"] == [
        {"steps": 256, "obs_size": [n_old, UNIVERSAL_OBS_SIZE]}]
    wide, wide_norm = load_policy(out)
    assert wide.observation_space.shape == (UNIVERSAL_OBS_SIZE,) and wide.num_timesteps == 256
    rng = np.random.default_rng(3)
    for _ in range(5):
        obs = rng.normal(size=UNIVERSAL_OBS_SIZE).astype(np.float32)
        a_old, _ = narrow.predict(narrow_norm.normalize_obs(obs[None, :n_old]), deterministic=True)
        a_new, _ = wide.predict(wide_norm.normalize_obs(obs[None]), deterministic=True)
        np.testing.assert_allclose(a_new, a_old, atol=1e-6)
    state, names = wide.policy.optimizer.state_dict()["state"], [n for n, _ in wide.policy.named_parameters()]
    for k in first:
        moments, before = state[names.index(k)]["exp_avg_sq"], opt["state"][names.index(k)]["exp_avg_sq"]
        np.testing.assert_array_equal(moments[:, :n_old].numpy(), before.numpy())
        assert not moments[:, n_old:].any()
    last = train_universal((src,), p, up, out, scenarios, total_steps=512, n_envs=2, resume=True, gate=False)
    assert last["steps"] == 512 and last["widened"] == again["widened"]  # widened once, then resumed as usual


def test_teachers_pull_the_policy_toward_their_actions_on_their_own_bodies(universal, camargo, policies_root,
                                                                          tmp_path):
    """Kickstarting (`Teachers`): camargo's committed policy teaching on camargo's own body. After the
    same short run with and without its term in PPO's loss, the policy's actions on camargo's states
    are nearer the teacher's with it; the saved optimizer is PPO's own; a teacher must be one of the
    run's subjects."""
    p, up, scenarios = universal
    p = replace(p, n_steps=128, batch_size=128, n_epochs=20, learning_rate=1e-3, checkpoint_steps=512,
                net_arch=(32, 32), target_kl=1e9)  # every epoch runs: the teacher's pull moves the policy far
    src = camargo[0]
    teacher, teacher_norm = load_policy(policies_root / "camargo")
    body = make_body(src, camargo[2], None, p.env, 0)
    walk, rng = [], np.random.default_rng(0)
    obs, _ = body.env.reset(seed=0)
    for _ in range(200):  # camargo's states under its own policy, a little noise on its actions
        walk.append(obs)
        action, _ = teacher.predict(teacher_norm.normalize_obs(obs[None]), deterministic=True)
        obs, _, fell, _, _ = body.env.step(np.clip(action[0] + rng.normal(0, 0.2, action.shape[1]), -1, 1))
        if fell:
            obs, _ = body.env.reset(seed=len(walk))
    walk = np.array(walk)
    target, _ = teacher.predict(teacher_norm.normalize_obs(walk), deterministic=True)
    error = {}
    for weight in (0.0, 50.0):
        taught = replace(up, teachers=("camargo",), teacher_weight=weight, teacher_batch=64)
        out = tmp_path / f"taught_{weight}"
        rec = train_universal((src,), p, taught, out, scenarios, total_steps=512, n_envs=2, gate=False,
                              teacher_root=policies_root)
        assert rec["runs"][-1].get("teachers") == (["camargo"] if weight else None)
        model, norm = load_policy(out)
        full = np.hstack([walk, np.repeat(body.obs[None], len(walk), 0)])
        action, _ = model.predict(norm.normalize_obs(full), deterministic=True)
        error[weight] = float(np.mean(np.square(action - target)))
        assert not model.policy.optimizer._optimizer_step_pre_hooks  # the term's hook left with the run
    assert error[50.0] < 0.85 * error[0.0], error
    pool = MultiBodyEnv((src,), up, p.env, seed=0)
    with pytest.raises(ValueError, match="'opencap4' is not one of universal.subjects"):
        load_teachers(("opencap4",), pool, policies_root)


def test_the_action_bound_brings_means_past_the_bounds_back(universal, camargo, tmp_path):
    """`ActionBound`: a run whose policy means for three actions sit past the bound (+2, where the env
    clips to +1) resumed the same way with and without the term. With it, the share of mean actions
    past the bound on the pool's states falls to under half of the share without it; the record names
    the term's weight; the term's hook leaves with the run; however large its weight, the term's
    gradient is clipped with PPO's."""
    p, up, scenarios = universal
    p = replace(p, n_steps=128, batch_size=128, n_epochs=20, learning_rate=3e-3, checkpoint_steps=256,
                net_arch=(32, 32), target_kl=1e9)  # every epoch runs
    up = replace(up, min_action_std=None, bound_weight=0.0, bound_batch=64)
    src, base = camargo[0], tmp_path / "base"
    train_universal((src,), p, up, base, scenarios, total_steps=256, n_envs=2, gate=False)
    model, norm = load_policy(base)
    with torch.no_grad():
        model.policy.action_net.bias[:3] += 2.0
    model.save(str(base / "policy.zip"))
    env, rng, raw = MultiBodyEnv((src,), up, p.env, seed=1), np.random.default_rng(1), []
    obs, _ = env.reset(seed=1)
    for i in range(256):  # the pool's states, random actions
        raw.append(obs)
        obs, _, fell, cut, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        if fell or cut:
            obs, _ = env.reset(seed=2 + i)
    states = torch.as_tensor(norm.normalize_obs(np.array(raw)), dtype=torch.float32)
    share0 = float(beyond_bound(model, states).mean())
    assert share0 >= 2.0 / model.action_space.shape[0]
    term = ActionBound(1e6, 64)  # however large, the term's gradient is clipped with PPO's
    term.model, term.x = model, states
    term._init_callback()
    term._add_term(model.policy.optimizer, (), {})
    grads = [q.grad.norm() for q in model.policy.parameters() if q.grad is not None]
    assert grads and 0 < float(torch.norm(torch.stack(grads))) <= model.max_grad_norm + 1e-6
    term._on_training_end()
    assert not model.policy.optimizer._optimizer_step_pre_hooks
    share = {}
    for weight in (0.0, 10.0):
        out = tmp_path / f"bound_{weight}"
        shutil.copytree(base, out)
        rec = train_universal((src,), p, replace(up, bound_weight=weight), out, scenarios, total_steps=1024,
                              n_envs=2, resume=True, gate=False)
        assert rec["runs"][-1].get("bound_weight") == (weight or None)
        trained, _ = load_policy(out)
        share[weight] = float(beyond_bound(trained, states).mean())
        assert not trained.policy.optimizer._optimizer_step_pre_hooks  # the term's hook left with the run
    assert share[10.0] < 0.5 * share[0.0], (share0, share)


def test_the_body_observation_keeps_its_first_values(camargo):
    """A policy trained on fewer body values reads the first ones (`BODY_OBS_SIZES`)."""
    _, model, cycle = camargo
    full = body_observation(model, cycle)
    np.testing.assert_array_equal(body_observation(model, cycle, BODY_OBS_SIZES[0]), full[:BODY_OBS_SIZES[0]])
    assert full[-2] > 0.03  # camargo's standing centre of mass is ahead of its ankles (/ leg length)
    with pytest.raises(ValueError, match="not 6"):
        body_observation(model, cycle, 6)


def test_the_universal_params_reject_unknown_keys():
    with pytest.raises(KeyError, match="universal: unknown key 'drwan'"):
        UniversalParams.from_dict({"drwan": 3})
    with pytest.raises(KeyError, match="universal.bodies: unknown key"):
        UniversalParams.from_dict({"bodies": {"rnage": 0.1, "range": 0.1, "segment_jitter": 0.0}})
    with pytest.raises(KeyError, match="universal.bodies: missing key 'segment_jitter'"):
        UniversalParams.from_dict({"bodies": {"range": 0.1}})
    with pytest.raises(KeyError, match="universal: missing key 'adaptive_share'"):
        UniversalParams.from_dict({"subjects": ["camargo"]})
    with pytest.raises(KeyError, match="universal.env: 'push_probabilty' is not a train.env key"):
        UniversalParams.from_dict({"env": {"push_probabilty": 0.25}})
    with pytest.raises(ValueError, match="push_force_n"):  # typed as train.env is
        UniversalParams.from_dict({"env": {"push_force_n": "strong"}})


def test_throughput_is_measured_against_the_physics(universal, camargo):
    from sim.learn.throughput import measure

    p, up, scenarios = universal
    doc = measure((camargo[0],), up, replace(p, n_steps=64, batch_size=128), scenarios, n_envs=2,
                  device="cpu", init_from="data/policies/camargo", env_steps=100, train_steps=128,
                  in_process_envs=3)
    assert doc["cpu_count"] >= 1 and doc["workers"] == 2
    assert doc["in_process_envs"] == 3 and doc["update_threads"] == doc["cpu_count"]
    for label in ("one", "all", "in_process"):
        # an env step is 15 physics steps (30 ms policy, 2 ms physics) plus the env's own work; the two
        # rates are measured one after the other, so a busy machine's noise gets a factor of 2
        physics = doc[f"mj_step_per_s_{'one' if label == 'in_process' else label}"]  # in_process: one process
        assert 0 < doc[f"env_steps_per_s_{label}"] < physics / 5
        assert 0 < doc[f"train_steps_per_s_{label}"]
        assert doc[f"train_to_env_{label}"] == pytest.approx(
            doc[f"train_steps_per_s_{label}"] / doc[f"env_steps_per_s_{label}"], abs=1e-3)


def test_throughput_resumes_a_copy_of_the_run_and_leaves_the_run_alone(universal, camargo, tmp_path):
    """The measurement's training from the committed run's checkpoint: a copy resumed, so the
    rate is the run's own policy and statistics going on, and the run's files stay as they were."""
    from sim.learn.throughput import train_step_rate

    p, up, scenarios = universal
    run = tmp_path / "run"
    universal_module.copy_checkpoint(os.path.join("data", "universal"), run)
    before = {f.name: f.read_bytes() for f in run.iterdir()}
    rate = train_step_rate((camargo[0],), up, replace(p, n_steps=64, batch_size=64), scenarios, 1, 128,
                           "cpu", "data/policies/nowhere", resume_from=run)
    assert rate > 0
    assert {f.name: f.read_bytes() for f in run.iterdir()} == before


def test_grouped_workers_step_as_one_process_does(universal, camargo):
    from functools import partial

    from sim.learn.vec import GroupedSubprocVecEnv

    p, up, _ = universal
    fns = [partial(MultiBodyEnv, (camargo[0],), replace(up, drawn=1), p.env, 10 + i) for i in range(5)]
    one, grouped = DummyVecEnv(fns), GroupedSubprocVecEnv(fns, 2)
    try:
        assert [len(g) for g in grouped.groups] == [2, 3]
        for v in (one, grouped):
            v.seed(3)
        a, b = one.reset(), grouped.reset()
        np.testing.assert_array_equal(a, b)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(60):  # long enough for some episodes to end and reset
            act = rng.uniform(-1, 1, (5, 21)).astype(np.float32)
            (oa, ra, da, ia), (ob, rb, db, ib) = one.step(act), grouped.step(act)
            np.testing.assert_array_equal(oa, ob)
            np.testing.assert_array_equal(ra, rb)
            np.testing.assert_array_equal(da, db)
            for x, y in zip(ia, ib, strict=True):
                if "terminal_observation" in x:
                    np.testing.assert_array_equal(x["terminal_observation"], y["terminal_observation"])
            ended += int(da.sum())
        assert ended > 0
        assert grouped.get_attr("current", [3])[0].source == "camargo"
        grouped.set_attr("marker", 7, [1, 4])
        assert grouped.get_attr("marker", [1, 4]) == [7, 7]
        for proc in grouped.processes:  # a terminal's Ctrl-C reaches the env processes too
            os.kill(proc.pid, signal.SIGINT)
        grouped.step(act)  # they ignore it: the main process ends the run (StopOnSignal)
        assert all(proc.is_alive() for proc in grouped.processes)
    finally:
        one.close()
        grouped.close()


def test_the_recorded_command_names_no_path_of_this_machine(tmp_path, monkeypatch):
    from sim.learn.universal import shown_path

    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").mkdir()
    assert shown_path(str(tmp_path / "data" / "universal")) == "data/universal"
    assert shown_path("/somewhere/else/u") == "<outside>/u"
    assert [shown_path(a) for a in ("--resume", "--n-envs", "16")] == ["--resume", "--n-envs", "16"]
    assert shown_path(str(tmp_path / "data" / "universal"), root=tmp_path / "data") == "universal"
