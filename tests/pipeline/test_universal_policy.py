"""A subject's policy folder exported from the committed universal policy walks through the same
rollout machinery as a single-body policy (sim.learn.universal.export_subject, PolicySource with
`BodyConditioned`)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from pipeline.paths import UNIVERSAL_DIR
from pipeline.runs.jobs import policy_setup, scenario_jobs
from sim.learn.bodies import BODY_OBS_SIZE, BODY_OBS_SIZES, body_observation
from sim.learn.policy_human import ActorMlp, BodyConditioned
from sim.learn.pool import UNIVERSAL_OBS_SIZE, Source
from sim.learn.train import NORM_FILE, POLICY_FILE, load_body, load_policy
from sim.learn.universal import UNIVERSAL_FILE, export_subject
from sim.learn.walk_env import OBS_SIZE, make_walk_env
from sim.rollout.batch import run_batch


def test_an_exported_subject_policy_walks_its_own_body(params, train_params, camargo_model, policies_root,
                                                         tmp_path):
    universal = UNIVERSAL_DIR
    src = Source("camargo", str(camargo_model / "human.xml"), str(camargo_model / "reference.npz"))
    p = train_params()
    folder = export_subject(universal, src, p.env, tmp_path / "camargo")
    assert (folder / UNIVERSAL_FILE).is_file()
    model, norm = load_policy(folder)
    assert model.observation_space.shape == (UNIVERSAL_OBS_SIZE,)
    # what rollouts need: the run's actor, no critic, an optimizer without training's moments
    run, _ = load_policy(universal)
    weights, kept = run.policy.state_dict(), model.policy.state_dict()
    actor = [k for k in weights if "value_net" not in k]
    assert "action_net.weight" in actor and all(torch.equal(kept[k], weights[k]) for k in actor)
    assert len(model.policy.mlp_extractor.value_net) == 0 and not model.policy.value_net.weight.any()
    assert model.policy.optimizer.state_dict()["state"] == {} and run.policy.optimizer.state_dict()["state"]
    assert (folder / POLICY_FILE).stat().st_size < 0.25 * (universal / POLICY_FILE).stat().st_size

    # the body the policy is told about is the folder's own
    xml, cycle = load_body(folder)
    env = make_walk_env(xml, cycle, p.env)
    body = body_observation(env.model, cycle)
    actor = ActorMlp.from_sb3(model, norm)
    obs = np.random.default_rng(0).normal(size=OBS_SIZE)
    np.testing.assert_array_equal(BodyConditioned(actor, body)(obs), actor(np.concatenate([obs, body])))

    setup = policy_setup("camargo", params, camargo_model.parents[1], tmp_path)
    outcomes = run_batch(setup, scenario_jobs(params, ("free",), 1, ("steady",)), 1, "", False)
    assert len(outcomes) == 1 and outcomes[0].stable
    assert len(outcomes[0].pelvis_xy) > 100


def _first_body_values_only(folder: Path, body: np.ndarray, n_body: int) -> None:
    """`folder`'s export rewritten as one trained on the first `n_body` body values: the first layers'
    weights on the later values folded into their biases, for `body` (exact for that body alone)."""
    model, norm = load_policy(folder)
    n = OBS_SIZE + n_body
    z = np.clip((body[n_body:] - norm.obs_rms.mean[n:]) / np.sqrt(norm.obs_rms.var[n:] + norm.epsilon),
                -norm.clip_obs, norm.clip_obs)
    for net in (model.policy.mlp_extractor.policy_net, model.policy.mlp_extractor.value_net):
        if not len(net):  # an actor-only export: its zero value head reads the observation itself
            model.policy.value_net = torch.nn.Linear(n, 1)
            continue
        old = net[0]
        first = torch.nn.Linear(n, old.out_features)
        with torch.no_grad():
            first.weight.copy_(old.weight[:, :n])
            first.bias.copy_(old.bias + old.weight[:, n:] @ torch.as_tensor(z, dtype=old.weight.dtype))
        net[0] = first
    space = gym.spaces.Box(-np.inf, np.inf, (n,), np.float32)
    model.observation_space = model.policy.observation_space = norm.observation_space = space
    norm.obs_rms.mean, norm.obs_rms.var = norm.obs_rms.mean[:n], norm.obs_rms.var[:n]
    model.save(str(folder / POLICY_FILE))
    norm.class_attributes, norm.returns = {}, None  # what pickling drops (a loaded one lacks them)
    norm.save(str(folder / NORM_FILE))


def test_an_export_from_before_body_values_were_appended_reads_the_first_ones(params, train_params,
                                                                              camargo_model, tmp_path):
    """An export from when the body observation had five values (`BODY_OBS_SIZES`; kgc6's 60.93 M
    export was one): the policy source gives it the first five of the body's values. Made here from
    camargo's export with the later values' weights folded into the biases, so it walks as the full
    export does only when it is given the right five."""
    src = Source("camargo", str(camargo_model / "human.xml"), str(camargo_model / "reference.npz"))
    p = train_params()
    full, old = (export_subject(UNIVERSAL_DIR, src, p.env, tmp_path / f / "camargo") for f in ("full", "old"))
    xml, cycle = load_body(full)
    body = body_observation(make_walk_env(xml, cycle, p.env).model, cycle)
    _first_body_values_only(old, body, BODY_OBS_SIZES[0])
    model, _ = load_policy(old)
    assert model.observation_space.shape[0] - OBS_SIZE == BODY_OBS_SIZES[0] < BODY_OBS_SIZE
    jobs = scenario_jobs(params, ("free",), 1, ("steady",))
    walks = [run_batch(policy_setup("camargo", params, camargo_model.parents[1], tmp_path / f), jobs, 1, "",
                       False)[0] for f in ("full", "old")]
    assert all(w.stable and len(w.pelvis_xy) > 100 for w in walks)
    first_s = int(params.section("rollout.policy_sample_rate_hz", float))  # the first second's samples
    np.testing.assert_allclose(walks[1].pelvis_xy[:first_s], walks[0].pelvis_xy[:first_s], atol=1e-3)
