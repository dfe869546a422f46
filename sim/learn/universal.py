"""One walking policy for many bodies: PPO + AMP over the bundled subjects' humans and bodies drawn
around them, the body in the observation.

Every env holds a pool of bodies (`sim.learn.pool.MultiBodyEnv`): each bundled subject's scaled human
with its own reference cycle, and `UniversalParams.drawn` bodies drawn around them
(`sim.learn.bodies`: segment lengths and masses within +-15 %, the cycle carried over by dynamic
similarity), one per episode. The observation is the walking env's (`OBS_SIZE`) followed by
`body_observation` (`BODY_OBS_SIZE`). The discriminator's reference transitions come from every
body's cycle alike, and `motion_share` of them from the subjects' whole recordings and their mirror
images (their starts, stops and turns).

The run starts from a single-body policy (`init_from`, e.g. camargo's committed one), its first
layers widened with zero weights for the body inputs (`widen_for_body`), so it walks from step
one; it is ONE run that resumes from its own folder (`resume`). A run resumed after body values were
appended to the observation is widened the same way for them, its optimizer state kept (`widened`
in the record); one resumed with wider hidden layers (`UniversalParams.net_arch`) is widened acting
as before (`widen_layers`, also in `widened`); one taken back to an earlier checkpoint of its own
(`--rewind-from`) keeps the branch it gave up (`discarded`). At every checkpoint it writes the
policy, the observation statistics, the discriminator and `progress.json`: steps, wall time and
`quick_gate` (each subject's body, its cycle: walk_10m and turn_90, no fall, standing at the end,
steady speed within the bound) against steps.

Run it with `python -m sim.learn.universal` (flags: `--help`; Ctrl-C or SIGTERM stops it with a
checkpoint, `StopOnSignal`); it needs numpy, torch, mujoco, gymnasium, stable-baselines3, pyyaml,
and pandas and scipy for the scenarios' commands: no Ray, DuckDB or DVC.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import sys
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

from sim.learn.amp import AMP, AMPCallback
from sim.learn.bodies import BODY_OBS_SIZE, BODY_OBS_SIZES
from sim.learn.pool import UNIVERSAL_OBS_SIZE, MultiBodyEnv, Source, UniversalParams, make_body
from sim.learn.train import (
    AMP_FILE,
    NORM_FILE,
    POLICY_FILE,
    PROGRESS_FILE,
    Budget,
    MetricsLog,
    StopOnSignal,
    TrainParams,
    UpdateThreads,
    closed_on_error,
    learn_for,
    load_norm,
    load_policy,
    new_ppo,
    ppo_settings,
    save_body,
    save_for_rollouts,
    save_steering,
)
from sim.learn.vec import GroupedSubprocVecEnv
from sim.learn.walk_env import AMP_SIZE, OBS_SIZE, WalkEnvParams, motion_amp_pairs
from sim.motion.reference import load_reference, mirrored_motion
from sim.rollout.scenarios import ProfileParams, Segment, command_profile

UNIVERSAL_FILE = "universal.json"  # in a subject's policy folder exported from the universal one
RUN_STATE = (POLICY_FILE, NORM_FILE, AMP_FILE)  # what the run resumes from, beside its PROGRESS_FILE


def amp_reference_sampler(pool: MultiBodyEnv, up: UniversalParams, dt_s: float, seed: int):
    """`n -> (n, 2 x AMP)` reference transitions: every body of `pool` alike (the subjects' own
    first), `up.motion_share` of them from the recordings (each subject's own body) and their mirror
    images."""
    sources = pool.sources
    tables = [(b.env.ref, b.env.step_phase) for b in pool.bodies]
    recorded = []
    if up.motion_share > 0:
        for s, b in zip(sources, pool.bodies, strict=False):
            m = load_reference(s.reference_npz)
            for q, v in ((m.qpos, m.qvel), mirrored_motion(b.env.model, m.qpos, m.qvel)):
                recorded.append(motion_amp_pairs(b.env.model, m.time_s, q, v, m.trial, dt_s,
                                                 m.cycle.floor_shift_m))
    motion = np.vstack(recorded) if recorded else np.empty((0, 2 * AMP_SIZE))
    rng = np.random.default_rng(seed)

    def sample(n: int) -> np.ndarray:
        m = int(rng.binomial(n, up.motion_share)) if len(motion) else 0
        counts = rng.multinomial(n - m, np.full(len(tables), 1.0 / len(tables)))
        parts = [ref.amp_pairs(rng, c, step) for (ref, step), c in zip(tables, counts, strict=True) if c]
        if m:
            parts.append(motion[rng.integers(0, len(motion), m)])
        out = np.vstack(parts)
        return out[rng.permutation(len(out))]

    return sample


def widen_for_body(old: PPO, old_norm: VecNormalize, venv, p: TrainParams, body_mean: np.ndarray,
                   body_std: np.ndarray, *, optimizer: bool = False) -> tuple[VecNormalize, PPO]:
    """A policy with `UNIVERSAL_OBS_SIZE` inputs that acts exactly as `old` whatever the inputs it
    lacks: a single-body policy (`OBS_SIZE` inputs) or a body-conditioned one trained on fewer body
    values (`sim.learn.bodies.BODY_OBS_SIZES`). The first layers of the policy and value networks get
    the added inputs (the last ones) with zero weights, the old inputs keep their weights and
    normalisation statistics, the added ones are normalised by `body_mean`, `body_std` (the pool's),
    and the statistics stay fixed: updated by other bodies' observations, they would change what
    the old inputs mean to the network. `optimizer`: Adam's moments carried over too (zero for the
    added weights), so a resumed run goes on as it was; otherwise a fresh optimizer."""
    n_old = old.observation_space.shape[0]
    if n_old - OBS_SIZE not in (0, *BODY_OBS_SIZES[:-1]) or len(body_mean) != UNIVERSAL_OBS_SIZE - n_old:
        raise ValueError(f"the start policy has {n_old} observations: not the walking env's {OBS_SIZE} "
                         f"followed by fewer body values than {BODY_OBS_SIZE} {BODY_OBS_SIZES}, or "
                         f"{len(body_mean)} statistics for {UNIVERSAL_OBS_SIZE - n_old} added inputs")
    norm = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0, gamma=p.gamma)
    mean = np.concatenate([old_norm.obs_rms.mean, body_mean])
    var = np.concatenate([old_norm.obs_rms.var, np.square(body_std) - norm.epsilon])
    norm.obs_rms.mean, norm.obs_rms.var, norm.obs_rms.count = mean, var, old_norm.obs_rms.count
    norm.training = False
    model = new_ppo(norm, p)
    keys = [f"mlp_extractor.{net}.0.weight" for net in ("policy_net", "value_net")]
    state = {k: v.clone() for k, v in old.policy.state_dict().items()}
    for key in keys:
        state[key] = _pad_columns(state[key])
    model.policy.load_state_dict(state)
    if optimizer:
        names = [n for n, _ in old.policy.named_parameters()]
        opt = old.policy.optimizer.state_dict()
        for key in keys:
            moments = opt["state"].get(names.index(key), {})
            for m in ("exp_avg", "exp_avg_sq"):
                if m in moments:
                    moments[m] = _pad_columns(moments[m])
        model.policy.optimizer.load_state_dict(opt)
    return norm, model


def hidden_sizes(model: PPO) -> tuple[int, ...]:
    """The widths of a PPO policy's hidden layers (its policy network's; the value network's match)."""
    net = model.policy.mlp_extractor.policy_net
    return tuple(m.out_features for m in net if isinstance(m, torch.nn.Linear))


ADDED_UNIT_SCALE = 0.1  # x the fresh network's incoming weights of an added unit (widen_layers)


def widen_layers(old: PPO, venv, p: TrainParams, sizes: tuple[int, ...]) -> PPO:
    """A PPO whose policy and value networks have hidden layers `sizes` (as many as `old`'s, none
    narrower) that acts and values exactly as `old` (Net2WiderNet, Chen, Goodfellow & Shlens 2016,
    in its simplest form): the added units get the fresh network's random incoming weights x
    `ADDED_UNIT_SCALE` and zero outgoing ones, so no layer after them uses them until training moves
    those weights. Scaled, because a trained layer's units are small and sparse, and Adam moves
    the outgoing weights of larger added units so far that one PPO step leaves the KL bound
    (measured in docs/results.md, "The universal walking policy"). Adam's
    moments are carried over; the added weights' first moments start at zero and their second at
    their tensor's mean, so that their first steps are no larger than the others' (zero would make
    them many learning rates long: the step count, hence no bias correction, is carried over too).
    Why: more units for more bodies without starting the run again."""
    before = hidden_sizes(old)
    if len(sizes) != len(before) or any(a < b for a, b in zip(sizes, before, strict=True)):
        raise ValueError(f"universal.net_arch {list(sizes)}: the run's layers {list(before)} can only be "
                         "widened (as many layers, none narrower)")
    model = new_ppo(venv, replace(p, net_arch=tuple(sizes)))
    model.num_timesteps = old.num_timesteps
    model._n_updates = old._n_updates
    state = model.policy.state_dict()
    index = {n: i for i, (n, _) in enumerate(old.policy.named_parameters())}  # the optimizer's numbering
    opt_old = old.policy.optimizer.state_dict()
    opt_new = {"state": {}, "param_groups": opt_old["param_groups"]}
    for name, w_old in old.policy.state_dict().items():
        w = state[name].clone()
        block = tuple(slice(0, n) for n in w_old.shape)
        if name.startswith("mlp_extractor."):  # an added hidden unit's incoming weights and bias
            w[w_old.shape[0]:] *= ADDED_UNIT_SCALE
        if w.dim() == 2 and w.shape[1] > w_old.shape[1]:  # inputs from added units: unused for now
            w[:, w_old.shape[1]:] = 0.0
        w[block] = w_old.cpu()
        state[name] = w
        moments = opt_old["state"].get(index.get(name), {})
        if moments:
            grown = {k: v for k, v in moments.items() if k == "step"}
            grown["exp_avg"] = torch.zeros_like(w)
            grown["exp_avg_sq"] = torch.full_like(w, float(moments["exp_avg_sq"].mean()))
            for k in ("exp_avg", "exp_avg_sq"):
                grown[k][block] = moments[k].cpu()
            opt_new["state"][index[name]] = grown
    model.policy.load_state_dict(state)
    model.policy.optimizer.load_state_dict(opt_new)
    return model


def pool_observations(model: PPO, venv: VecNormalize, steps: int) -> np.ndarray:
    """Raw observations of about `steps` env steps of the pool walking under `model`'s stochastic
    actions, as in training (steps, UNIVERSAL_OBS_SIZE); not counted as training steps, and `venv`'s
    statistics left as they are."""
    learning, venv.training = venv.training, False
    try:
        obs, out = venv.reset(), []
        for _ in range(-(-steps // venv.num_envs)):
            action, _ = model.predict(obs, deterministic=False)
            obs, _, _, _ = venv.step(action)
            out.append(venv.get_original_obs())
    finally:
        venv.training = learning
    return np.concatenate(out)[:steps]


def restat(model: PPO, norm: VecNormalize, obs: np.ndarray) -> dict:
    """In place: `norm`'s observation statistics re-estimated from `obs` (raw observations of the
    pool, `pool_observations`), and the first layers of the policy and value networks carried over so
    that an input inside both clip ranges gives the same pre-activations as before (w' = w s_new /
    s_old, b' = b + w (mu_new - mu_old) / s_old; Adam's moments of w as the gradient scales, m / r and
    v / r^2). An input the old statistics put past the clip (`clip_obs`) reaches the network unclipped
    now. Why: a run started from one body's policy keeps that body's statistics, and a body whose
    joints sit far outside them (another subject's arms, say) feeds the network clipped, constant
    inputs (docs/policies.md). Returns the samples and the shares of them with an input past the
    clip before and after."""
    rms, clip = norm.obs_rms, norm.clip_obs
    mean_old, scale_old = rms.mean.copy(), np.sqrt(rms.var + norm.epsilon)
    mean_new, var_new = obs.mean(0), obs.var(0)
    scale_new = np.sqrt(var_new + norm.epsilon)
    before = float((np.abs(obs - mean_old) > clip * scale_old).any(1).mean())
    after = float((np.abs(obs - mean_new) > clip * scale_new).any(1).mean())
    state = model.policy.optimizer.state
    with torch.no_grad():
        for net in (model.policy.mlp_extractor.policy_net, model.policy.mlp_extractor.value_net):
            w, b = net[0].weight, net[0].bias
            as_w = partial(torch.as_tensor, dtype=w.dtype, device=w.device)
            b += w @ as_w((mean_new - mean_old) / scale_old)
            ratio = as_w(scale_new / scale_old)
            w *= ratio
            moments = state.get(w, {})
            if "exp_avg" in moments:
                moments["exp_avg"] /= ratio
                moments["exp_avg_sq"] /= ratio ** 2
    rms.mean, rms.var, rms.count = mean_new, var_new, float(len(obs))
    return {"samples": len(obs), "clipped_before": round(before, 4), "clipped_after": round(after, 4)}


def _pad_columns(w: torch.Tensor) -> torch.Tensor:
    out = torch.zeros((w.shape[0], UNIVERSAL_OBS_SIZE), dtype=w.dtype)
    out[:, :w.shape[1]] = w
    return out


def mean_action_parameters(policy) -> list[torch.nn.Parameter]:
    """The weights of a PPO policy's mean action (its policy network and action layer)."""
    return [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters()]


class CriticWarmup(BaseCallback):
    """The first `steps` env steps of a run started from a single-body policy update the value
    network only: its values were learnt on one body, and advantages from them would first push the
    walking policy about on bodies it has never seen."""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _on_rollout_start(self) -> None:
        for prm in [*mean_action_parameters(self.model.policy), self.model.policy.log_std]:
            prm.requires_grad_(self.num_timesteps >= self.steps)

    def _on_step(self) -> bool:
        return True


class StdFloor(BaseCallback):
    """Keeps the policy's action standard deviation (state-independent, per action) at or above
    `min_std` (normalised action units), raised before each rollout. Why: PPO's updates stop at a KL
    budget, and between Gaussians of std s the mean moves only ~s sqrt(2 KL / actions) per update, so a
    shrinking std also shrinks how far each update can move the policy."""

    def __init__(self, min_std: float) -> None:
        super().__init__()
        self.floor = math.log(min_std)

    def _on_rollout_start(self) -> None:
        with torch.no_grad():
            self.model.policy.log_std.clamp_(min=self.floor)

    def _on_step(self) -> bool:
        return True


class TrainingRecord(BaseCallback):
    """What training itself saw between two checkpoints, for the progress record (`take`): each
    body's episodes and falls, in all and in the episodes with random pushes, and the command phase
    of each fall without them (`calm_fell_in`; `sim.learn.pool.MultiBodyEnv`'s `pool_episode`: a
    subject's own body by name, every drawn body as `drawn`) and PPO's updates (approximate KL, clip
    fraction, epochs run of `n_epochs` before `target_kl` stopped them, explained variance, action
    std, and `beyond_bound`: the share of the rollout's mean actions past the action bounds, where
    the env clips them, `ActionBound`), each update also to `log(step, metrics)`. Why: the quick gate
    walks each body once per check; this is every episode."""

    PPO_KEYS = ("approx_kl", "clip_fraction", "explained_variance", "std")
    COUNTS = ("episodes", "falls", "pushed", "pushed_falls")

    def __init__(self, log) -> None:
        super().__init__()
        self.log_fn = log
        self.episodes: dict[str, dict] = {}
        self.updates: list[dict] = []
        self.n_updates = 0
        self.beyond: float | None = None

    def _init_callback(self) -> None:
        self.n_updates = self.model._n_updates

    def _on_rollout_end(self) -> None:  # before PPO's update of this rollout
        self.beyond = float(beyond_bound(self.model, rollout_states(self.model)).mean())

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "pool_episode" in info:
                body, fell, pushed, phase = info["pool_episode"]
                row = self.episodes.setdefault(body, {**dict.fromkeys(self.COUNTS, 0), "calm_fell_in": {}})
                for key, hit in zip(self.COUNTS, (True, fell, pushed, fell and pushed), strict=True):
                    row[key] += int(hit)
                if fell and not pushed:
                    row["calm_fell_in"][phase] = row["calm_fell_in"].get(phase, 0) + 1
        return True

    def _on_rollout_start(self) -> None:  # after PPO's update of the last rollout (SB3 records it)
        seen = self.model.logger.name_to_value
        if self.model._n_updates == self.n_updates or "train/approx_kl" not in seen:
            return
        row = {k: float(seen[f"train/{k}"]) for k in self.PPO_KEYS if f"train/{k}" in seen}
        row["epochs"] = float(self.model._n_updates - self.n_updates)
        if self.beyond is not None:
            row["beyond_bound"] = self.beyond
        self.n_updates = self.model._n_updates
        self.updates.append(row)
        self.log_fn(self.num_timesteps, {f"ppo_{k}": v for k, v in row.items()})

    def take(self) -> dict:
        """{"episodes": {body: {count: n} (`COUNTS`), "calm_fell_in": {phase: n}}, "ppo": {statistic:
        mean over the updates}, "updates": n} since the last `take`; the counts start again."""
        keys = sorted({k for u in self.updates for k in u})
        out = {"episodes": dict(sorted(self.episodes.items())),
               "ppo": {k: round(float(np.mean([u[k] for u in self.updates if k in u])), 5) for k in keys},
               "updates": len(self.updates)}
        self.episodes, self.updates = {}, []
        return out


def rollout_states(model: PPO) -> torch.Tensor:
    """The last rollout's observations as the policy saw them (normalised), one row per state."""
    seen = model.rollout_buffer.observations
    return torch.as_tensor(seen.reshape(-1, seen.shape[-1]), device=model.device)


def excess(model: PPO, x: torch.Tensor) -> torch.Tensor:
    """Per state of `x` and action, how far the policy's mean action is past the action space's
    bounds (0 inside them), in normalised action units."""
    mean = model.policy.get_distribution(x).distribution.mean
    high = torch.as_tensor(model.action_space.high, dtype=mean.dtype, device=mean.device)
    return torch.relu(mean.abs() - high)


def beyond_bound(model: PPO, x: torch.Tensor) -> torch.Tensor:
    """Per state of `x`, the share of the policy's mean actions past the action space's bounds."""
    with torch.no_grad():
        return (excess(model, x) > 0).float().mean(-1)


class LossTerm(BaseCallback):
    """A term of PPO's loss on the policy's mean action, beside PPO's own: before each of PPO's
    optimizer steps (a pre-step hook) the gradient of `loss()` on the mean action's weights is added
    to PPO's and the sum clipped to PPO's `max_grad_norm`, as PPO clips its own, so one optimizer
    weighs both at the gradient scale its moments know (added unclipped, a large term inflated Adam's
    second moments and wrecked the policy in one update). Subclasses give `loss()` (None: nothing
    this step), each on `batch` states drawn at each step (`pick`)."""

    def __init__(self, batch: int, seed: int = 0) -> None:
        super().__init__()
        self.batch = batch
        self.rng = np.random.default_rng(seed)
        self.hook = None

    def _init_callback(self) -> None:
        self.hook = self.model.policy.optimizer.register_step_pre_hook(self._add_term)

    def loss(self) -> torch.Tensor | None:
        raise NotImplementedError

    def pick(self, n: int, device) -> torch.Tensor:
        """`batch` random indices below `n`, drawn with replacement (`n` of them where `n` is smaller)."""
        return torch.as_tensor(self.rng.integers(0, n, min(self.batch, n)), device=device)

    def _add_term(self, optimizer, args, kwargs) -> None:
        params = [q for q in mean_action_parameters(self.model.policy) if q.requires_grad]
        if not params:  # the critic's warm-up: the mean action is not trained
            return
        with torch.enable_grad():
            loss = self.loss()
            if loss is None:
                return
            grads = torch.autograd.grad(loss, params)
        for q, g in zip(params, grads, strict=True):
            q.grad = g if q.grad is None else q.grad + g
        torch.nn.utils.clip_grad_norm_(self.model.policy.parameters(), self.model.max_grad_norm)

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        if self.hook is not None:
            self.hook.remove()
            self.hook = None


class ActionBound(LossTerm):
    """The action-bound term of AMP's reference implementations (Peng et al. 2021, 2022; rl_games'
    `bounds_loss`, MimicKit's `action_bound_weight`): `weight` x the squared excess of the mean action
    past the action space's bounds, summed over actions and averaged over `batch` states of the
    rollout drawn at each optimizer step. Why: the env clips each sampled action to the bounds, so
    for a mean far past them every sample acts alike and PPO's gradient on that mean is noise; the
    term brings it back to where its samples differ (it does not change the clipped action until the
    mean is inside)."""

    def __init__(self, weight: float, batch: int, seed: int = 0) -> None:
        super().__init__(batch, seed)
        self.weight = weight
        self.x: torch.Tensor | None = None

    def _on_rollout_end(self) -> None:  # before PPO's update of this rollout
        self.x = rollout_states(self.model)

    def loss(self) -> torch.Tensor | None:
        if self.x is None:
            return None
        x = self.x[self.pick(len(self.x), self.x.device)]
        return self.weight * torch.square(excess(self.model, x)).sum(-1).mean()


Teacher = tuple[np.ndarray, PPO, VecNormalize]  # a teacher's body observation, policy, observation statistics


class Teachers(LossTerm):
    """Kickstarting (Schmitt et al. 2018, "Kickstarting deep reinforcement learning") from committed
    single-body policies, DAgger-style (Ross, Gordon & Bagnell 2011): the rollout's states on a
    teacher's own body (`teachers`: that body's observation, the teacher and its observation
    statistics), labelled with the teacher's deterministic action, add `weight` x the squared error
    of the policy's mean action, averaged over the whole rollout (other states add nothing), to
    PPO's loss (`LossTerm`, on `batch` of those states at each optimizer step): one optimizer, so
    PPO's own terms weigh against it (a separate Adam moved every weight a learning rate per step
    toward one body and took every other body down). `log(step, metrics)` receives the squared error
    before and after each update and the states."""

    def __init__(self, teachers: list[Teacher], weight: float, batch: int, log, seed: int = 0) -> None:
        super().__init__(batch, seed)
        self.teachers, self.weight, self.log_fn = teachers, weight, log
        self.raw: list[np.ndarray] = []
        self.x: torch.Tensor | None = None
        self.y: torch.Tensor | None = None
        self.share, self.before = 0.0, 0.0

    def _init_callback(self) -> None:
        super()._init_callback()
        self.norm = self.model.get_vec_normalize_env()  # raw observations: which body, the teacher input

    def labelled(self, seen: np.ndarray, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the rows of `seen`, observations as the policy saw them, whose `raw` observation is on a
        teacher's body, the teacher's actions for them)."""
        xs, ys = [seen[:0]], [np.zeros((0, self.model.action_space.shape[0]), np.float32)]
        for body, teacher, norm in self.teachers:
            hit = np.all(raw[:, OBS_SIZE:] == body, axis=1)
            if hit.any():
                action, _ = teacher.predict(norm.normalize_obs(raw[hit, :OBS_SIZE]), deterministic=True)
                xs.append(seen[hit])
                ys.append(np.asarray(action, np.float32))
        return np.vstack(xs), np.vstack(ys)

    def _on_step(self) -> bool:
        self.raw.append(self.norm.get_original_obs().copy())  # the next row's
        return True

    def _error(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        return torch.square(self.model.policy.get_distribution(x).distribution.mean - y).mean()

    def _on_rollout_end(self) -> None:  # before PPO's update of this rollout
        seen = self.model.rollout_buffer.observations
        raw = np.stack(self.raw[:len(seen)])
        x, y = self.labelled(seen.reshape(-1, seen.shape[-1]), raw.reshape(-1, raw.shape[-1]))
        dev = self.model.device
        self.x, self.y = torch.as_tensor(x, device=dev), torch.as_tensor(y, device=dev)
        self.share = len(x) / (seen.shape[0] * seen.shape[1])
        if len(x):
            with torch.no_grad():
                self.before = float(self._error(self.x, self.y))

    def _on_rollout_start(self) -> None:  # after PPO's update of the last rollout
        if self.x is not None and len(self.x):
            with torch.no_grad():
                after = float(self._error(self.x, self.y))
            self.log_fn(self.num_timesteps, {"teacher_error_before": self.before,
                                             "teacher_error_after": after, "teacher_states": len(self.x)})
        self.x = None
        self.raw = [self.norm.get_original_obs().copy()]  # the first row's

    def loss(self) -> torch.Tensor | None:
        if self.x is None or not len(self.x):
            return None
        idx = self.pick(len(self.x), self.x.device)
        return self.weight * self.share * self._error(self.x[idx], self.y[idx])


def load_teachers(names: tuple[str, ...], pool: MultiBodyEnv, root: Path) -> list[Teacher]:
    """`Teachers`' teachers: each named subject's committed policy in `root/<name>` (a single-body one,
    `OBS_SIZE` observations) with its own body's observation from `pool`."""
    out = []
    for name in names:
        own = [b for b in pool.bodies if b.source == name and b.scales is None]
        if not own:
            raise ValueError(f"universal.teachers: {name!r} is not one of universal.subjects")
        model, norm = load_policy(root / name)
        if model.observation_space.shape[0] != OBS_SIZE or norm is None:
            raise ValueError(f"{root / name / POLICY_FILE}: a teacher must be a single-body policy "
                             f"({OBS_SIZE} observations, not {model.observation_space.shape[0]}) "
                             f"with its {NORM_FILE}")
        out.append((own[0].obs, model, norm))
    return out


def make_pool_env(sources: tuple[Source, ...], up: UniversalParams, p: WalkEnvParams,
                  seed: int) -> MultiBodyEnv:
    """One env process's pool of bodies (one torch thread: the envs never run torch)."""
    torch.set_num_threads(1)
    return MultiBodyEnv(sources, up, p, seed)


def quick_gate(model: PPO, norm: VecNormalize, sources: tuple[Source, ...], up: UniversalParams,
               p: WalkEnvParams, scenarios: dict[str, list[Segment]]) -> dict:
    """Each subject's own body walking `up.gate_scenarios` (deterministic actions, no pushes,
    `up.gate_seeds` start phases; a scenario that starts from standing walks the same walk for
    every seed): per subject and scenario, no fall in any walk (`fell_in`: the scenario phase of
    each fall) and standing at the end; walk_10m's steady speed within `gate_speed_tolerance` of
    the cycle's. Returns {subject: {check: {"pass", "value"}}}, plus `passed` and `checks` counts."""
    out: dict = {}
    passed = total = 0
    for src in sources:
        cycle = load_reference(src.reference_npz).cycle
        rows: dict = {}
        body = make_body(src, cycle, None, replace(p, episode_s=120.0, push_probability=0.0), 0)
        env = body.env
        for name in up.gate_scenarios:
            prof = command_profile(name, scenarios[name], cycle.speed_mps, 1.0 / env.dt, p.profile)
            falls, standing, speeds, fell_in = 0, 0, [], []
            for seed in range(up.gate_seeds):
                obs, _ = env.reset(seed=seed, options={"commands": prof, "pushes": False,
                                                       "phase": seed / max(up.gate_seeds, 1)})
                v, steady = [], prof.phase == "steady"
                for k in range(len(prof.time_s)):
                    x = norm.normalize_obs(np.concatenate([obs, body.obs])[None])
                    action, _ = model.predict(x, deterministic=True)
                    obs, _, fell, _, _ = env.step(action[0])
                    h = prof.heading_rad[min(k + 1, len(prof.time_s) - 1)]
                    v.append(math.cos(h) * env.data.qvel[0] + math.sin(h) * env.data.qvel[1])
                    if fell:
                        falls += 1
                        fell_in.append(str(prof.phase[k]))
                        break
                else:
                    last = np.abs(v[-int(round(1.0 / env.dt)):])
                    standing += int(last.max() < up.gate_standing_mps)
                    if steady.any():
                        at = steady[np.minimum(np.arange(len(v)) + 1, len(steady) - 1)]  # step k: command k+1
                        speeds.append(float(np.mean(np.asarray(v)[at])))
            rows[f"{name}_no_fall"] = {"pass": falls == 0, "value": falls, "fell_in": fell_in}
            rows[f"{name}_standing_at_end"] = {"pass": standing == up.gate_seeds, "value": standing}
            if name == "walk_10m":
                err = float(np.mean(speeds)) / cycle.speed_mps - 1.0 if speeds else None
                ok = err is not None and abs(err) <= up.gate_speed_tolerance
                rows["walk_10m_steady_speed"] = {"pass": ok, "value": None if err is None else round(err, 4)}
        out[src.name] = rows
        passed += sum(r["pass"] for r in rows.values())
        total += len(rows)
    return {"subjects": out, "passed": passed, "checks": total}


def device_of(name: str) -> str:
    """`auto`: cuda when torch sees a GPU, else cpu."""
    return ("cuda" if torch.cuda.is_available() else "cpu") if name == "auto" else name


def train_universal(sources: tuple[Source, ...], p: TrainParams, up: UniversalParams, out_dir: str | Path,
                    scenarios: dict[str, list[Segment]], *, init_from: str | Path | None = None,
                    resume: bool = False, total_steps: int | None = None, n_envs: int | None = None,
                    subprocess: bool = False, max_wall_s: float | None = None, device: str = "auto",
                    threads: int = 1, command: str = "", progress: bool = False, gate: bool = True,
                    workers: int | None = None, teacher_root: str | Path = "data/policies",
                    restat_steps: int = 0) -> dict:
    """Train (or resume) the universal policy into `out_dir` (module docstring); returns the
    progress record. `subprocess`: the envs in `workers` processes (default one per env,
    `sim.learn.vec.GroupedSubprocVecEnv`); `gate`: False skips `quick_gate` at the checkpoints;
    `teacher_root`: where `up.teachers`' committed policies are (`Teachers`); `restat_steps`: a
    resumed run's observation statistics first re-estimated from this many steps of the pool
    (`restat`, recorded in `statistics`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    device = device_of(device)
    torch.set_num_threads(threads)
    n_envs = n_envs or p.n_envs
    env = replace(p.env, **up.env)  # the training envs; the gate walks `p.env`'s (pushes off either way)
    if up.learning_rate is not None:  # PPO's own (the loads below take it through `ppo_settings`)
        p = replace(p, learning_rate=up.learning_rate)
    fns = [partial(make_pool_env, sources, up, env, p.seed * 1000 + 37 * i) for i in range(n_envs)]
    vec = GroupedSubprocVecEnv(fns, workers or n_envs) if subprocess and n_envs > 1 else DummyVecEnv(fns)
    with closed_on_error(vec):  # the env processes end with the run, also when it raises
        venv = VecMonitor(vec)
        resumed = resume and (out / PROGRESS_FILE).exists()
        prior = json.loads((out / PROGRESS_FILE).read_text()) if resumed else {}
        # the AMP references and the body statistics
        pool = MultiBodyEnv(sources, replace(up, refresh_probability=0.0), env, p.seed)
        body_obs = np.array([b.obs for b in pool.bodies])
        frozen = bool(prior.get("obs_stats_frozen")) if prior else init_from is not None
        widened, discarded = list(prior.get("widened", [])), list(prior.get("discarded", []))
        if prior and int(prior.get("obs_size", UNIVERSAL_OBS_SIZE)) < UNIVERSAL_OBS_SIZE:  # values appended
            old = PPO.load(str(out / POLICY_FILE), device="cpu", custom_objects=ppo_settings(p))
            n_old = old.observation_space.shape[0] - OBS_SIZE
            venv, model = widen_for_body(old, load_norm(out), venv, p, body_obs[:, n_old:].mean(0),
                                         np.maximum(body_obs[:, n_old:].std(0), 0.02), optimizer=True)
            model.num_timesteps = old.num_timesteps
            widened.append({"steps": int(old.num_timesteps),
                            "obs_size": [OBS_SIZE + n_old, UNIVERSAL_OBS_SIZE]})
            if device != "cpu":
                model = _to_device(model, venv, p, device)
        elif prior:
            venv = VecNormalize.load(str(out / NORM_FILE), venv)
            venv.training = not frozen
            model = PPO.load(str(out / POLICY_FILE), env=venv, device=device, custom_objects=ppo_settings(p))
        elif init_from is not None:
            old = PPO.load(str(Path(init_from) / POLICY_FILE), device="cpu")
            venv, model = widen_for_body(old, load_norm(Path(init_from)), venv, p, body_obs.mean(0),
                                         np.maximum(body_obs.std(0), 0.02))
            if device != "cpu":
                model = _to_device(model, venv, p, device)
        else:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0, gamma=p.gamma)
            model = new_ppo(venv, p) if device == "cpu" else _to_device(new_ppo(venv, p), venv, p, device)
        before = hidden_sizes(model)
        if up.net_arch and before != up.net_arch:
            model = widen_layers(model, venv, p, up.net_arch)
            widened.append({"steps": int(model.num_timesteps), "net_arch": [list(before), list(up.net_arch)]})
            if device != "cpu":
                model = _to_device(model, venv, p, device)
        statistics = list(prior.get("statistics", []))
        if restat_steps:
            if not prior:
                raise ValueError("restat_steps: only a resumed run's observation statistics are re-estimated")
            statistics.append({"steps": int(model.num_timesteps),
                               **restat(model, venv, pool_observations(model, venv, restat_steps))})
        sampler = amp_reference_sampler(pool, up, pool.bodies[0].env.dt, p.seed)
        amp = AMP(2 * AMP_SIZE, p.amp, sampler, seed=p.seed, device=device)
        start_amp = out if prior else (Path(init_from) if init_from is not None else None)
        if start_amp is not None and (start_amp / AMP_FILE).exists():
            amp.load_state_dict(torch.load(start_amp / AMP_FILE, weights_only=False, map_location=device))
        log = MetricsLog(out, resume=bool(prior))
        start = time.perf_counter()
        steps0, wall0 = int(prior.get("steps", 0)), float(prior.get("wall_s", 0.0))
        runs, checkpoints = list(prior.get("runs", [])), list(prior.get("checkpoints", []))
        origin = {k: v for k, v in prior.items() if k.startswith("initial")} or (
            {"initialised_from": str(init_from)} if init_from is not None else {})
        if not prior:
            model.num_timesteps = 0
        total = total_steps or p.total_steps
        gate_wall = [0.0]
        taught = bool(up.teachers) and up.teacher_weight > 0

        def save() -> dict:
            model.save(str(out / POLICY_FILE))
            venv.save(str(out / NORM_FILE))
            torch.save(amp.state_dict(), out / AMP_FILE)
            wall = round(wall0 + time.perf_counter() - start, 1)
            if gate:
                t0 = time.perf_counter()
                g = quick_gate(model, venv, sources, up, p.env, scenarios)
                gate_wall[0] += time.perf_counter() - t0
                checkpoints.append({"steps": int(model.num_timesteps), "wall_s": wall, "passed": g["passed"],
                                    "checks": g["checks"], "gate": g["subjects"],
                                    **({"training": record.take()} if record.num_timesteps else {})})
            run_steps = int(model.num_timesteps) - steps0
            run_wall = time.perf_counter() - start
            rec = {"steps": int(model.num_timesteps), "wall_s": wall, **origin,
                   "subjects": [s.name for s in sources], "obs_size": UNIVERSAL_OBS_SIZE,
                   "obs_stats_frozen": frozen, **({"widened": widened} if widened else {}),
                   **({"statistics": statistics} if statistics else {}),
                   **({"discarded": discarded} if discarded else {}),
                   "runs": runs + [{"command": command, "n_envs": n_envs, "subprocess": subprocess,
                                    **({"teachers": list(up.teachers)} if taught else {}),
                                    **({"env": {k: list(v) if isinstance(v, tuple) else v
                                                for k, v in up.env.items()}} if up.env else {}),
                                    **({} if up.min_action_std is None else
                                       {"min_action_std": up.min_action_std}),
                                    **({"bound_weight": up.bound_weight} if up.bound_weight > 0 else {}),
                                    **({} if up.learning_rate is None else
                                       {"learning_rate": up.learning_rate}),
                                    **({} if env.commands.first_step == "either" else
                                       {"first_step": env.commands.first_step}),
                                    "workers": workers,
                                    "device": device, "threads": threads, "cpu_count": os.cpu_count(),
                                    "steps": run_steps,
                                    "wall_s": round(run_wall, 1), "gate_wall_s": round(gate_wall[0], 1),
                                    "steps_per_s": round(run_steps / max(run_wall - gate_wall[0], 1e-9), 1)}],
                   "checkpoints": checkpoints}
            tmp = out / f".{PROGRESS_FILE}.tmp"
            tmp.write_text(progress_text(rec))
            os.replace(tmp, out / PROGRESS_FILE)
            if progress and gate:
                print(f"{rec['steps']} steps, {wall:.0f} s: gate {g['passed']}/{g['checks']}", flush=True)
            return rec

        record, stop = TrainingRecord(log), StopOnSignal()
        callbacks = [UpdateThreads(threads), AMPCallback(amp, p.env.w_style, 6, log), record,
                     Budget(total, p.checkpoint_steps, save, max_wall_s, False), stop]
        if up.min_action_std is not None:
            callbacks.insert(0, StdFloor(up.min_action_std))
        if not prior and init_from is not None and up.critic_warmup_steps > 0:
            callbacks.append(CriticWarmup(up.critic_warmup_steps))
        if taught:
            callbacks.append(Teachers(load_teachers(up.teachers, pool, Path(teacher_root)), up.teacher_weight,
                                      up.teacher_batch, log, p.seed))
        if up.bound_weight > 0:
            callbacks.append(ActionBound(up.bound_weight, up.bound_batch, p.seed))
        callbacks = CallbackList(callbacks)
        if not prior and gate:
            save()  # the curve's origin: the start policy's gate
        learn_for(model, max(total - steps0, 0), callbacks, stop, fresh=not prior)
        rec = save() if not checkpoints or checkpoints[-1]["steps"] != model.num_timesteps else \
            json.loads((out / PROGRESS_FILE).read_text())
        if stop.caught and progress:
            print(f"stopped by {stop.caught.name} at {model.num_timesteps} steps, saved", flush=True)
        log.close()
        venv.close()
    stop.carry_on()  # after the with: a caught signal's error is not the block's, its envs closed
    return rec


def _to_device(model: PPO, venv: VecNormalize, p: TrainParams, device: str) -> PPO:
    """`model`'s weights in a PPO on `device`."""
    moved = PPO("MlpPolicy", venv, **ppo_settings(p), seed=p.seed, device=device, verbose=0,
                policy_kwargs=model.policy_kwargs)
    moved.policy.load_state_dict(model.policy.state_dict())
    moved.policy.optimizer.load_state_dict(model.policy.optimizer.state_dict())  # moved to its device
    moved.num_timesteps = model.num_timesteps
    return moved


def export_subject(universal_dir: str | Path, src: Source, p: WalkEnvParams, out_dir: str | Path,
                   label: str | None = None) -> Path:
    """A subject's policy folder from the universal policy, as `sim.learn.train.train` lays one out
    (policy, observation statistics, body, cycle, speed law), so the policy human, evaluate-policy and
    the rollout stages use it unchanged (`sim.learn.policy_human.BodyConditioned` adds the body);
    `universal.json` names the checkpoint it came from (`label`, default the folder's path)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    src_dir = Path(universal_dir)
    save_for_rollouts(src_dir / POLICY_FILE, out / POLICY_FILE, critic=False)  # what rollouts need: the actor
    shutil.copyfile(src_dir / NORM_FILE, out / NORM_FILE)
    save_body(out, src.xml, load_reference(src.reference_npz).cycle)
    save_steering(out, p.commands)
    rec = json.loads((src_dir / PROGRESS_FILE).read_text())
    origin = {"universal": label or str(src_dir), "steps": rec["steps"],
              "fine_tuned_steps": rec.get("fine_tuned_steps", 0)}
    (out / UNIVERSAL_FILE).write_text(json.dumps(origin) + "\n")
    return out


def fine_tune_body(universal_dir: str | Path, src: Source, p: TrainParams, up: UniversalParams,
                   work_dir: str | Path, *, steps: int, max_wall_s: float | None = None, command: str = "",
                   progress: bool = False) -> dict:
    """The universal policy fine-tuned on one body (`src`'s own, no drawn bodies, no teachers): the
    transfer stage's fine-tune of a subject the universal policy does not walk yet. The run continues
    the universal one's weights, observation statistics (frozen) and discriminator in `work_dir`,
    resuming there; `steps`: env steps of fine-tuning in all. Returns the progress record, with
    `fine_tuned_steps` (this fine-tune's env steps) and `initial_steps` (the universal policy's)."""
    work = Path(work_dir)
    if not (work / PROGRESS_FILE).exists():
        start = int(copy_checkpoint(universal_dir, work)["steps"])
        first = {"steps": start, "wall_s": 0.0, "initialised_from": "universal", "initial_steps": start,
                 "obs_stats_frozen": True, "runs": [], "checkpoints": []}
        (work / PROGRESS_FILE).write_text(progress_text(first))
    start = int(json.loads((work / PROGRESS_FILE).read_text())["initial_steps"])
    alone = replace(up, drawn=0, adaptive_share=0.0, teachers=(), net_arch=None)  # the policy as it is
    rec = train_universal((src,), p, alone, work, {}, resume=True, total_steps=start + steps,
                          max_wall_s=max_wall_s, command=command, progress=progress, gate=False)
    rec = {**rec, "fine_tuned_steps": int(rec["steps"]) - start}
    (work / PROGRESS_FILE).write_text(progress_text(rec))
    return rec


def progress_text(rec: dict) -> str:
    """A run's progress record as JSON text: a line per key and a compact line per record in a list
    of records (checkpoints, runs, branches given up), so each checkpoint adds one line, a diff
    stays readable and the committed file is 0.6 of its indented size."""
    def text(value) -> str:
        if isinstance(value, list) and value and all(isinstance(x, dict) for x in value):
            return "[\n" + ",\n".join("  " + json.dumps(x, separators=(",", ":")) for x in value) + "\n ]"
        return json.dumps(value)
    return "{\n" + ",\n".join(f" {json.dumps(k)}: {text(v)}" for k, v in rec.items()) + "\n}\n"


def rewound(current: dict, earlier: dict, why: str) -> dict:
    """The progress record of a run taken back to an earlier checkpoint of its own (`earlier`: the
    record as that checkpoint wrote it): `earlier`, with the branch given up appended to `discarded`
    (from and to steps, `why`, its training wall time, runs and checkpoints), so the curve keeps what
    was tried and the run's `wall_s` stays the time behind the policy it holds."""
    at, end = int(earlier["steps"]), int(current["steps"])
    if at >= end or at not in {c["steps"] for c in current.get("checkpoints", [])} or \
            current.get("runs", [])[:len(earlier.get("runs", []))] != earlier.get("runs", []):
        raise ValueError(f"rewind: the record at {at} steps is not an earlier checkpoint of this run "
                         f"(at {end} steps)")
    branch = {"from_steps": at, "to_steps": end, "why": why,
              "wall_s": round(float(current["wall_s"]) - float(earlier["wall_s"]), 1),
              "runs": current["runs"][len(earlier.get("runs", [])):],
              "checkpoints": [c for c in current["checkpoints"] if c["steps"] > at]}
    return {**earlier, "discarded": [*current.get("discarded", []), branch]}


def checkpoint_record(folder: str | Path) -> dict:
    """The progress record of the run's checkpoint in `folder`, checked whole first (`RUN_STATE`
    and `PROGRESS_FILE`): a clear error naming the folder and what it lacks."""
    folder = Path(folder)
    missing = [name for name in (*RUN_STATE, PROGRESS_FILE) if not (folder / name).is_file()]
    if missing:
        raise FileNotFoundError(f"{folder}: missing {', '.join(missing)} (a checkpoint of the run is "
                                f"{', '.join(RUN_STATE)} and {PROGRESS_FILE})")
    return json.loads((folder / PROGRESS_FILE).read_text())


def copy_checkpoint(src_dir: str | Path, dst_dir: str | Path) -> dict:
    """The run's checkpoint in `src_dir` copied into `dst_dir` (made if needed), so a measurement,
    a fine-tune or a rewind starts from it without touching the run: its progress record."""
    rec, dst = checkpoint_record(src_dir), Path(dst_dir)
    dst.mkdir(parents=True, exist_ok=True)
    for name in (*RUN_STATE, PROGRESS_FILE):
        shutil.copyfile(Path(src_dir) / name, dst / name)
    return rec


def rewind(out_dir: Path, earlier_dir: Path, why: str) -> dict:
    """Take the run in `out_dir` back to the checkpoint saved in `earlier_dir` (its policy,
    statistics, discriminator and progress record, e.g. from an earlier commit): `rewound`."""
    rec = rewound(json.loads((out_dir / PROGRESS_FILE).read_text()), checkpoint_record(earlier_dir), why)
    copy_checkpoint(earlier_dir, out_dir)
    (out_dir / PROGRESS_FILE).write_text(progress_text(rec))
    return rec


# -- command line: reads params.yaml and data/processed directly (no pipeline imports) -------------

def sources_of(subjects: tuple[str, ...], processed: Path) -> tuple[Source, ...]:
    """The bundled subjects' scaled humans and references under `processed` (checked to exist)."""
    out = []
    for s in subjects:
        xml, npz = processed / s / "model" / "human.xml", processed / s / "model" / "reference.npz"
        for f in (xml, npz):
            if not f.exists():
                raise FileNotFoundError(f"{f}: missing (run `python -m pipeline run reference` first)")
        out.append(Source(s, str(xml), str(npz)))
    return tuple(out)


def params_from_yaml(path: Path) -> tuple[TrainParams, UniversalParams, dict[str, list[Segment]]]:
    """`train` (with the scenarios' transition timing), `universal` and the scenarios' segments."""
    import yaml
    from pydantic import TypeAdapter

    doc = yaml.safe_load(path.read_text())
    p = TypeAdapter(TrainParams).validate_python(doc["train"])
    p = replace(p, env=replace(p.env, profile=ProfileParams(**doc["scenarios"]["profile"])))
    up = UniversalParams.from_dict(doc["universal"])
    scenarios = {k: [Segment(**seg) for seg in v] for k, v in doc["scenarios"]["commands"].items()}
    return p, up, scenarios


def shown_path(arg: str, root: Path | None = None) -> str:
    """An argument as a committed record keeps it: an absolute path relative to `root` (default: the
    working directory), or, outside it, `<outside>/<name>`; anything else as given (no path of one
    machine in a committed record)."""
    if not os.path.isabs(arg):
        return arg
    path, here = Path(arg).resolve(), (root or Path.cwd()).resolve()
    return str(path.relative_to(here)) if path.is_relative_to(here) else f"<outside>/{path.name}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim.learn.universal", description=__doc__.split("\n")[0])
    ap.add_argument("--params", type=Path, default=Path("params.yaml"))
    ap.add_argument("--processed", type=Path, default=Path("data/processed"))
    ap.add_argument("--out", type=Path, default=Path("data/universal"))
    ap.add_argument("--init-from", type=Path, default=None, help="single-body policy folder (default: "
                    "data/policies/<universal.init_from>)")
    ap.add_argument("--resume", action="store_true", help="continue the run in --out")
    ap.add_argument("--steps", type=int, default=None, help="total env steps of the run "
                    "(default train.total_steps)")
    ap.add_argument("--max-wall-s", type=float, default=None)
    ap.add_argument("--n-envs", type=int, default=None)
    ap.add_argument("--subprocess", action="store_true", help="envs in worker processes")
    ap.add_argument("--workers", type=int, default=None,
                    help="with --subprocess: processes (default one per env)")
    ap.add_argument("--device", default="auto", help="auto | cpu | cuda (the PPO and AMP updates)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads of the update")
    ap.add_argument("--checkpoint-steps", type=int, default=None)
    ap.add_argument("--restat-steps", type=int, default=0, help="with --resume: first re-estimate the "
                    "observation statistics from this many env steps of the pool, the networks carried over")
    ap.add_argument("--export-to", type=Path, default=None, help="write every subject's policy folder from "
                    "the policy in --out into this root (<root>/<subject>/) and stop")
    ap.add_argument("--rewind-from", type=Path, default=None, help="take the run in --out back to "
                    "its own earlier checkpoint saved here (the branch kept in `discarded`) and stop")
    ap.add_argument("--why", default="", help="with --rewind-from: the reason, kept in the record")
    args = ap.parse_args(argv)
    if args.rewind_from is not None:
        rec = rewind(args.out, args.rewind_from, args.why)
        gave_up = rec["discarded"][-1]["to_steps"]
        print(f"rewound to {rec['steps']} steps; the branch to {gave_up} steps kept in `discarded`")
        return 0
    p, up, scenarios = params_from_yaml(args.params)
    if args.export_to is not None:
        for src in sources_of(up.subjects, args.processed):
            print(export_subject(args.out, src, p.env, args.export_to / src.name))
        return 0
    if args.checkpoint_steps:
        p = replace(p, checkpoint_steps=args.checkpoint_steps)
    resume = args.resume and (args.out / PROGRESS_FILE).exists()
    init = None if resume else (args.init_from or Path("data/policies") / up.init_from)
    shown = map(shown_path, sys.argv[1:] if argv is None else argv)
    command = "python -m sim.learn.universal " + " ".join(shown)
    try:
        rec = train_universal(sources_of(up.subjects, args.processed), p, up, args.out, scenarios,
                              init_from=init, resume=resume, total_steps=args.steps, n_envs=args.n_envs,
                              subprocess=args.subprocess, workers=args.workers, max_wall_s=args.max_wall_s,
                              device=args.device, threads=args.threads, command=command, progress=True,
                              restat_steps=args.restat_steps)
    except KeyboardInterrupt:  # Ctrl-C: a run in training saved first (StopOnSignal); no traceback
        return 128 + signal.SIGINT
    last = rec["checkpoints"][-1]
    print(f"{rec['steps']} steps in {rec['wall_s']} s; gate {last['passed']}/{last['checks']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
