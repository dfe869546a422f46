"""PPO + adversarial motion prior training of the walking human (stable-baselines3, torch).

`train` builds `n_envs` `WalkEnv`s (one process with `DummyVecEnv`, or one process per env with
`SubprocVecEnv` on machines with many cores), normalises observations (`VecNormalize`), and runs
PPO with the `AMPCallback` (sim/learn/amp.py) adding the style reward. It writes, in `out_dir`:
`policy.zip` (SB3 PPO incl. optimiser), `vecnormalize.pkl` (observation statistics), `amp.pt`
(discriminator) and `progress.json` (steps, wall time, command); a run started with `resume=True`
continues from them; a run started with `init_from` (another subject's policy folder) begins from
that policy, its observation statistics and discriminator instead of from scratch (transfer: every
subject's human has the same joints, observation and action layout; only the body and the reference
cycle differ), and counts its own steps from zero; a straight walker from before steering (72
observations) is widened to the steering observation first (`widen_policy`). Checkpoints are
written every `checkpoint_steps` and when the wall-time budget ends the run.

PPO settings follow DeepMimic's (Peng et al. 2018: discount 0.95, GAE lambda 0.95, clip 0.2) with
SB3's Adam; network sizes are params.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, fields, replace
from functools import partial
from pathlib import Path

import mujoco
import numpy as np
import torch
from pydantic import with_config
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecMonitor, VecNormalize

from sim.body.variant import Variant
from sim.errors import SimulationError
from sim.learn.amp import AMP, AMPCallback, AMPParams
from sim.learn.steering import CommandSampling
from sim.learn.walk_env import (
    AMP_SIZE,
    LEGACY_OBS_SIZE,
    OBS_SIZE,
    WalkEnv,
    WalkEnvParams,
    make_walk_env,
    motion_amp_pairs,
)
from sim.motion.reference import Reference, ReferenceCycle, mirrored_motion, with_longer_swing

POLICY_FILE, NORM_FILE, AMP_FILE, PROGRESS_FILE = "policy.zip", "vecnormalize.pkl", "amp.pt", "progress.json"
BODY_FILE, CYCLE_FILE = "human.xml", "cycle.npz"  # the body and reference cycle the policy was trained on
LEAN_LAW = ("turn_lean_time_constant_s", "max_lean_tan")  # kept with `turn_lean` in STEERING_FILE
STEERING_FILE = "steering.json"  # the speed law it was trained under (sim/learn/steering.py)


@with_config(extra="forbid")
@dataclass(frozen=True)
class TrainSubject:
    """A subject with a committed policy (data/policies/<subject>/): its dvc `train` stage's extra
    `python -m pipeline train` arguments."""

    args: str = ""


@with_config(extra="forbid")
@dataclass(frozen=True)
class TrainParams:
    """The `train` section of params.yaml (PPO + AMP; `subjects` is the dvc `train` stage's list)."""

    total_steps: int = 3_700_000
    n_envs: int = 8
    threads: int = 1
    subprocess: bool = False
    n_steps: int = 256              # per env per rollout
    batch_size: int = 2048
    n_epochs: int = 5
    learning_rate: float = 2e-4
    gamma: float = 0.98             # DeepMimic's 0.95 before: a stop needs a longer horizon
    gae_lambda: float = 0.95        # DeepMimic
    clip_range: float = 0.2         # DeepMimic
    ent_coef: float = 0.0
    max_grad_norm: float = 0.5
    target_kl: float = 0.05
    log_std_init: float = -1.0
    net_arch: tuple[int, ...] = (256, 256)
    checkpoint_steps: int = 250_000
    seed: int = 0
    env: WalkEnvParams = field(default_factory=WalkEnvParams)
    amp: AMPParams = field(default_factory=AMPParams)
    subjects: dict[str, TrainSubject] = field(default_factory=dict)


def _make_env(model_path: str, cycle: ReferenceCycle, p: WalkEnvParams, seed: int) -> WalkEnv:
    torch.set_num_threads(1)
    return make_walk_env(model_path, cycle, p, seed=seed)


def make_vec_env(model_path: str | Path, cycle: ReferenceCycle, p: TrainParams, n_envs: int,
                 subprocess: bool) -> VecMonitor:
    fns = [partial(_make_env, str(model_path), cycle, p.env, p.seed * 1000 + i) for i in range(n_envs)]
    venv = SubprocVecEnv(fns, start_method="fork") if subprocess and n_envs > 1 else DummyVecEnv(fns)
    return VecMonitor(venv)


class _Curriculum(BaseCallback):
    """Fine-tuning a cohort variant from a healthy policy: the variant's torque limits and preferred
    speed ramp in linearly (`WalkEnv.variant_weight` 0 -> 1) over the first `steps` env steps, so
    the policy is never dropped into a body it cannot yet walk with (a curriculum, as Yu, Turk and
    Liu, SIGGRAPH 2018, fade out the assistance of their learning walkers)."""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _weight(self) -> None:
        self.training_env.set_attr("variant_weight", min(1.0, self.num_timesteps / self.steps))

    def _on_training_start(self) -> None:
        self._weight()

    def _on_rollout_start(self) -> None:
        self._weight()

    def _on_step(self) -> bool:
        return True


class UpdateThreads(BaseCallback):
    """Torch threads: one while a rollout is collected (a forward pass over a few observations per
    env step, where more threads only add overhead), `threads` for the AMP and PPO updates after it
    (the cores the envs leave idle then). Goes first in the callback list, before `AMPCallback`."""

    def __init__(self, threads: int) -> None:
        super().__init__()
        self.threads = threads

    def _on_rollout_start(self) -> None:
        torch.set_num_threads(1)

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        torch.set_num_threads(self.threads)


class Budget(BaseCallback):
    """Progress bar, periodic checkpoints and a wall-time limit."""

    def __init__(self, total: int, checkpoint_steps: int, save: Callable[[], None], max_wall_s: float | None,
                 progress: bool) -> None:
        super().__init__()
        self.total, self.every, self.save, self.max_wall_s = total, checkpoint_steps, save, max_wall_s
        self.progress = progress
        self.start = time.perf_counter()
        self.next_ckpt = checkpoint_steps
        self.bar = None

    def _on_training_start(self) -> None:
        self.start_steps = self.num_timesteps
        self.next_ckpt = self.num_timesteps + self.every
        if self.progress:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, initial=self.num_timesteps, unit="step", dynamic_ncols=True)

    def _on_step(self) -> bool:
        if self.bar is not None:
            self.bar.n = self.num_timesteps
            if self.n_calls % 50 == 0:
                self.bar.refresh()
        if self.num_timesteps >= self.next_ckpt:
            self.save()
            self.next_ckpt += self.every
        return self.max_wall_s is None or time.perf_counter() - self.start < self.max_wall_s

    def _on_training_end(self) -> None:
        if self.bar is not None:
            self.bar.close()


class StopOnSignal(BaseCallback):
    """Ends training at the next env step on SIGINT or SIGTERM (Ctrl-C, `kill PID`), so the run saves
    its checkpoint and progress record as at its wall-time limit instead of losing the steps trained
    since its last checkpoint; then `carry_on` gives the signal its own effect, so a caller (a
    stage under `dvc repro`) stops as well. `caught` is the signal; `restore` puts the earlier
    handlers back: at training's end, and by `learn_for` when training raises (SB3 calls no end hook
    then, and Ctrl-C would stay swallowed). The universal run's env processes ignore SIGINT
    (`sim.learn.vec`): a terminal's Ctrl-C reaches them too."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        super().__init__()
        self.caught: signal.Signals | None = None
        self.before: dict = {}

    def _on_training_start(self) -> None:
        self.before = {s: signal.signal(s, self._catch) for s in self.SIGNALS}

    def _catch(self, signum, frame) -> None:
        self.caught = signal.Signals(signum)

    def _on_step(self) -> bool:
        return self.caught is None

    def _on_training_end(self) -> None:
        self.restore()

    def restore(self) -> None:
        """The handlers from before training; nothing when they are back already."""
        for s, handler in self.before.items():
            signal.signal(s, handler)
        self.before = {}

    def carry_on(self) -> None:
        """The caught signal's effect, deferred until the run was saved: KeyboardInterrupt for SIGINT,
        exit status 128 + its number for SIGTERM (as the default handler's)."""
        if self.caught == signal.SIGINT:
            raise KeyboardInterrupt
        if self.caught is not None:
            raise SystemExit(128 + self.caught)


def learn_for(model: PPO, steps: int, callbacks: CallbackList, stop: StopOnSignal, *, fresh: bool) -> None:
    """`model.learn` for `steps` more env steps (0: none), with the signal handlers from before it
    back afterwards also when it raises (`StopOnSignal.restore`: SB3 calls no end hook on an error);
    `fresh`: the step count starts at 0 (a run that resumes goes on from its own)."""
    if steps:
        try:
            model.learn(total_timesteps=steps, callback=callbacks, reset_num_timesteps=fresh,
                        progress_bar=False)
        finally:
            stop.restore()


@contextlib.contextmanager
def closed_on_error(vec: VecEnv) -> Iterator[None]:
    """Closes `vec` (ends its env processes) when the block raises, and lets the error go on: a dead
    worker's pipe error while closing is dropped so the block's own is the one seen. A run that
    ends normally closes its envs itself."""
    try:
        yield
    except BaseException:
        with contextlib.suppress(OSError, EOFError):
            vec.close()
        raise


class MetricsLog:
    """Per-rollout metrics to dvclive (`Live(dir)`) when installed, else to `metrics.csv` (rows of
    step, metric, value). Each call appends its rows and rewrites the summary only: dvclive's
    `next_step` parses every row logged so far (for Studio, even with Studio off), a cost that grows
    with a long run's history (measured in docs/results.md, "The universal walking policy")."""

    def __init__(self, folder: Path, resume: bool) -> None:
        self.folder = folder
        try:
            from dvclive import Live
            self.live = Live(str(folder / "dvclive"), resume=resume, save_dvc_exp=False, dvcyaml=None)
        except ImportError:
            self.live = None
        self.csv_path = folder / "metrics.csv"

    def __call__(self, step: int, metrics: dict) -> None:
        if self.live is not None:  # not next_step(): dvclive 3.49 re-reads every logged row there
            self.live.step = int(step)
            for k, v in metrics.items():
                self.live.log_metric(f"train/{k}", float(v))
            self.live.make_summary()
            return
        new = not self.csv_path.exists()
        with self.csv_path.open("a", newline="") as f:  # long form: callers log different metrics
            w = csv.writer(f)
            if new:
                w.writerow(["step", "metric", "value"])
            w.writerows([step, k, f"{float(v):.6g}"] for k, v in metrics.items())

    def close(self) -> None:
        if self.live is not None:
            self.live.end()


def variant_cycle(model_path: str | Path, cycle: ReferenceCycle, variant: Variant) -> ReferenceCycle:
    """The reference cycle a cohort variant imitates: the subject's, with the variant's longer swing
    on one side when it has one (`Variant.swing_time_ratio`); saved beside its policy (`save_body`)."""
    if variant.swing_time_ratio is None:
        return cycle
    side, ratio = variant.swing_time_ratio
    return with_longer_swing(mujoco.MjModel.from_xml_path(str(model_path)), cycle, side, ratio)


def train(model_path: str | Path, cycle: ReferenceCycle, p: TrainParams, out_dir: str | Path, *,
          n_envs: int | None = None, threads: int | None = None, total_steps: int | None = None,
          resume: bool = False, max_wall_s: float | None = None, subprocess: bool | None = None,
          progress: bool = True, command: str = "", init_from: str | Path | None = None,
          curriculum_steps: int = 0, motion: Reference | None = None) -> dict:
    """Train (or continue training) the walking policy; returns the progress record (also written
    to `out_dir/progress.json`). `init_from`: a policy folder to start from (module docstring);
    `curriculum_steps`: ramp a cohort variant's body and speed in over this many steps (`_Curriculum`);
    `motion`: the subject's retargeted recording, `p.amp.motion_share` of the style reference."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cycle = variant_cycle(model_path, cycle, p.env.variant)
    n_envs = n_envs or p.n_envs
    torch.set_num_threads(threads or p.threads)
    total = total_steps or p.total_steps
    in_processes = p.subprocess if subprocess is None else subprocess
    vec = venv = make_vec_env(model_path, cycle, p, n_envs, in_processes)
    with closed_on_error(vec):  # the env processes end with the run, also when it raises
        resumed = resume and (out / PROGRESS_FILE).exists()
        prior = json.loads((out / PROGRESS_FILE).read_text()) if resumed else {}
        start_dir = out if prior else (Path(init_from) if init_from is not None else None)
        if start_dir is not None:
            for f in (POLICY_FILE, NORM_FILE):
                if not (start_dir / f).exists():
                    raise FileNotFoundError(f"{start_dir / f}: no policy to start from")
            old = PPO.load(str(start_dir / POLICY_FILE), device="cpu")
            n_obs = old.observation_space.shape[0]
            if n_obs not in (LEGACY_OBS_SIZE, OBS_SIZE):
                raise SimulationError(start_dir / POLICY_FILE, f"a policy of {n_obs} observations, not one "
                                      f"body's {OBS_SIZE}: a subject's export of the universal policy is "
                                      "fine-tuned by `transfer` (from data/universal)")
            if n_obs == LEGACY_OBS_SIZE:  # a straight walker: widen to steering
                venv, model = widen_policy(old, load_norm(start_dir), venv, p, cycle.speed_mps)
            else:
                venv = VecNormalize.load(str(start_dir / NORM_FILE), venv)
                venv.training = True
                # the run's own PPO settings, not the saved ones (PPO.load restores those)
                model = PPO.load(str(start_dir / POLICY_FILE), env=venv, device="cpu",
                                 custom_objects=ppo_settings(p))
            if not prior:
                model.num_timesteps = 0
        else:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0, gamma=p.gamma)
            model = new_ppo(venv, p)
        ref_env = make_walk_env(model_path, cycle, p.env)
        rng = np.random.default_rng(p.seed)
        recorded = None
        if motion is not None and p.amp.motion_share > 0.0:
            # the recording and its mirror image: Camargo's circuits turn one way only
            recorded = np.vstack([motion_amp_pairs(ref_env.model, motion.time_s, q, v, motion.trial,
                                                   ref_env.dt, cycle.floor_shift_m)
                                  for q, v in ((motion.qpos, motion.qvel),
                                               mirrored_motion(ref_env.model, motion.qpos, motion.qvel))])
        amp = AMP(2 * AMP_SIZE, p.amp, lambda n: ref_env.ref.amp_pairs(rng, n, ref_env.step_phase, recorded,
                                                                       p.amp.motion_share), seed=p.seed)
        if start_dir is not None and (start_dir / AMP_FILE).exists():
            amp.load_state_dict(torch.load(start_dir / AMP_FILE, weights_only=False))
        log = MetricsLog(out, resume=bool(prior))
        start = time.perf_counter()
        steps0 = int(prior.get("steps", 0))
        wall0 = float(prior.get("wall_s", 0.0))
        runs = list(prior.get("runs", []))
        origin = {}
        if not prior and init_from is not None:
            src_file = Path(init_from) / PROGRESS_FILE
            src = json.loads(src_file.read_text()) if src_file.exists() else {}
            shown = Path(init_from).resolve()
            shown = shown.relative_to(Path.cwd()) if shown.is_relative_to(Path.cwd()) else shown
            origin = {"initialised_from": str(shown), "initial_policy_steps": int(src.get("steps", 0))}
        model_sha = hashlib.sha256(Path(model_path).read_bytes()).hexdigest()[:16]

        def save() -> dict:
            save_body(out, model_path, cycle)
            save_steering(out, p.env.commands)
            model.save(str(out / POLICY_FILE))
            venv.save(str(out / NORM_FILE))
            torch.save(amp.state_dict(), out / AMP_FILE)
            rec = {"steps": int(model.num_timesteps), "wall_s": round(wall0 + time.perf_counter() - start, 1),
                   **{k: v for k, v in prior.items() if k.startswith("initial")}, **origin,
                   "runs": runs + [{"command": command, "human_xml_sha256_16": model_sha,
                                    "n_envs": n_envs, "threads": threads or p.threads,
                                    "steps": int(model.num_timesteps) - steps0,
                                    "wall_s": round(time.perf_counter() - start, 1)}]}
            last = rec["runs"][-1]
            rec["steps_per_s_last_run"] = round(last["steps"] / max(last["wall_s"], 1e-9), 1)
            (out / PROGRESS_FILE).write_text(json.dumps(rec, indent=2) + "\n")
            return rec

        stop = StopOnSignal()
        callbacks = [UpdateThreads(threads or p.threads), AMPCallback(amp, p.env.w_style, 6, log),
                     Budget(total, p.checkpoint_steps, save, max_wall_s, progress), stop]
        if curriculum_steps > 0:
            callbacks.append(_Curriculum(curriculum_steps))
        callbacks = CallbackList(callbacks)
        learn_for(model, max(total - steps0, 0), callbacks, stop, fresh=not prior)
        rec = save()
        log.close()
        venv.close()
    stop.carry_on()  # after the with: a caught signal's error is not the block's, its envs closed
    return rec


def ppo_settings(p: TrainParams) -> dict[str, float | int]:
    """PPO's optimisation settings from the params: a fresh run gets them, and so does a run that
    starts from or resumes a saved policy (`PPO.load` would otherwise keep the saved ones, so a
    fine-tune could not change its learning rate or horizon)."""
    return {"n_steps": p.n_steps, "batch_size": p.batch_size, "n_epochs": p.n_epochs,
            "learning_rate": p.learning_rate, "gamma": p.gamma, "gae_lambda": p.gae_lambda,
            "clip_range": p.clip_range, "ent_coef": p.ent_coef, "max_grad_norm": p.max_grad_norm,
            "target_kl": p.target_kl}


def new_ppo(venv: VecNormalize, p: TrainParams) -> PPO:
    """A fresh PPO with the params' settings on `venv`."""
    return PPO("MlpPolicy", venv, **ppo_settings(p), seed=p.seed, device="cpu", verbose=0,
               policy_kwargs={"net_arch": {"pi": list(p.net_arch), "vf": list(p.net_arch)},
                              "activation_fn": torch.nn.ReLU, "log_std_init": p.log_std_init})


# observation slots whose statistics steering changes: (mean, std) to normalise them with from now on
# (yaw sin / cos relative to the commanded heading, gait amplitude, commanded yaw rate; the commanded
# speed, slot 65, gets the cycle's speed +- 40 %)
STEERING_STATS = {7: (0.0, 0.5), 8: (0.8, 0.3), 72: (0.7, 0.4), 73: (0.0, 0.5)}
UNTRAINED_SLOTS = range(65, 72)  # commanded speed and harness wrench: constant in straight-walk training


def widen_policy(old: PPO, old_norm: VecNormalize, venv: VecMonitor, p: TrainParams,
                 speed_mps: float) -> tuple[VecNormalize, PPO]:
    """A steering policy that acts exactly as the straight walker `old` on its own observations:
    the first layers get the new inputs with zero weights, the inputs that straight walking held
    constant (commanded speed, wrench) lose their never-trained weights, and slots given new
    normalisation statistics (`STEERING_STATS`) have their weights and biases rescaled so the
    network sees the same pre-activations (z_old = (m_new - m_old) / s_old + s_new / s_old z_new)."""
    n_old = old.observation_space.shape[0]
    norm = VecNormalize(venv, norm_obs=True, norm_reward=False, clip_obs=10.0, gamma=p.gamma)
    m_old = old_norm.obs_rms.mean.astype(float)
    s_old = np.sqrt(old_norm.obs_rms.var.astype(float) + old_norm.epsilon)
    mean, std = np.zeros(OBS_SIZE), np.ones(OBS_SIZE)
    mean[:n_old], std[:n_old] = m_old, s_old
    stats = {**STEERING_STATS, 65: (speed_mps, 0.4 * speed_mps)}
    for i, (m, sd) in stats.items():
        mean[i], std[i] = m, sd
    norm.obs_rms.mean, norm.obs_rms.var = mean, std ** 2 - norm.epsilon
    norm.obs_rms.count = 1e5  # new statistics adapt, without swamping the old ones at once
    model = new_ppo(norm, p)
    state = {k: v.clone() for k, v in old.policy.state_dict().items()}
    for net in ("policy_net", "value_net"):
        w_key, b_key = f"mlp_extractor.{net}.0.weight", f"mlp_extractor.{net}.0.bias"
        w_old, b = state[w_key], state[b_key]
        w = torch.zeros((w_old.shape[0], OBS_SIZE), dtype=w_old.dtype)
        w[:, :n_old] = w_old
        for i in stats:
            if i < n_old and i not in UNTRAINED_SLOTS:
                w[:, i] = w_old[:, i] * float(std[i] / s_old[i])
                b = b + w_old[:, i] * float((mean[i] - m_old[i]) / s_old[i])
        w[:, list(UNTRAINED_SLOTS)] = 0.0
        state[w_key], state[b_key] = w, b
    model.policy.load_state_dict(state)
    return norm, model


def load_norm(folder: Path) -> VecNormalize:
    import pickle

    with (folder / NORM_FILE).open("rb") as f:
        return pickle.load(f)


def save_steering(out_dir: str | Path, c: CommandSampling) -> None:
    """The speed law a policy is trained under (`STEERING_FILE`, read by `policy_env`)."""
    law = {"stride_speed_exponent": c.stride_speed_exponent, "full_gait_fraction": c.full_gait_fraction}
    if c.min_cadence is not None:  # written only when set: the files of earlier policies stay as they are
        law["min_cadence"] = c.min_cadence
    if c.turn_lean is not None:
        law |= {"turn_lean": c.turn_lean, **{k: getattr(c, k) for k in LEAN_LAW}}
    if c.heading_lead_deg is not None:
        law["heading_lead_deg"] = c.heading_lead_deg
    if c.first_step != "either":
        law["first_step"] = c.first_step
    (Path(out_dir) / STEERING_FILE).write_text(json.dumps(law) + "\n")


def save_body(out_dir: str | Path, model_path: str | Path, cycle: ReferenceCycle) -> None:
    """Keep the human model and reference cycle a policy was trained on beside it: a policy is bound
    to that body (joint frames, segment lengths) and is evaluated on it."""
    out = Path(out_dir)
    src = Path(model_path).read_bytes()
    if not (out / BODY_FILE).exists() or (out / BODY_FILE).read_bytes() != src:
        (out / BODY_FILE).write_bytes(src)
    np.savez(out / CYCLE_FILE, **{f.name: np.asarray(getattr(cycle, f.name)) for f in fields(ReferenceCycle)})


def load_body(out_dir: str | Path) -> tuple[Path, ReferenceCycle]:
    """(human.xml path, reference cycle) a policy was trained on (`save_body`)."""
    out = Path(out_dir)
    with np.load(out / CYCLE_FILE, allow_pickle=False) as z:
        kw = {k: (z[k].item() if z[k].ndim == 0 else z[k]) for k in z.files}
    return out / BODY_FILE, ReferenceCycle(**kw)


def policy_env(out_dir: str | Path, env: WalkEnvParams) -> WalkEnvParams:
    """`env` under the speed law the policy in `out_dir` was trained with (`STEERING_FILE`); a policy
    from before the law was recorded has none and keeps the legacy law (exponent None); one from
    before `full_gait_fraction` was recorded keeps the params' value; one without `min_cadence` was
    trained without a cadence floor, one without `turn_lean` without leaning into turns. The steering
    lead (`heading_lead_deg`) is how the simulated person follows a turn: a policy that recorded one
    keeps it, any other walks with the params' lead. One without `first_step` starts from the closer
    of the cycle's leg crossings ("either")."""
    f = Path(out_dir) / STEERING_FILE
    law = json.loads(f.read_text()) if f.exists() else {}
    fraction = law.get("full_gait_fraction") or env.commands.full_gait_fraction
    lead = law.get("heading_lead_deg", env.commands.heading_lead_deg)
    first = law.get("first_step", "either")
    return replace(env, commands=replace(env.commands, stride_speed_exponent=law.get("stride_speed_exponent"),
                                         full_gait_fraction=fraction, min_cadence=law.get("min_cadence"),
                                         **{k: law.get(k, getattr(env.commands, k)) for k in LEAN_LAW},
                                         turn_lean=law.get("turn_lean"), heading_lead_deg=lead,
                                         first_step=first))


def save_for_rollouts(src: str | Path, dest: str | Path, *, critic: bool = True) -> None:
    """The PPO policy in `src` saved at `dest` with an Adam optimizer that has taken no step: the
    weights, and so every rollout, unchanged, without training's moments (a committed policy keeps
    what rollouts need: 0.74 MB instead of 2.2 MB; docs/policies.md, "Committed policies").
    `critic=False`: the actor alone, the value network cut to a zero linear head on the observation
    (`net_arch` vf `[]`; rollouts read only the actor): half the size, for a policy no run starts from."""
    model = PPO.load(str(src), device="cpu")
    if not critic:
        model.policy_kwargs = {**model.policy_kwargs,
                               "net_arch": {"pi": list(model.policy_kwargs["net_arch"]["pi"]), "vf": []}}
        actor = model.policy_class(model.observation_space, model.action_space, model.lr_schedule,
                                   **model.policy_kwargs)
        kept = {k: v for k, v in model.policy.state_dict().items()
                if not k.startswith(("mlp_extractor.value_net.", "value_net."))}
        with torch.no_grad():
            actor.value_net.weight.zero_()
            actor.value_net.bias.zero_()
        actor.load_state_dict({**actor.state_dict(), **kept})
        model.policy = actor
    used = model.policy.optimizer
    model.policy.optimizer = type(used)(model.policy.parameters(), **used.defaults)
    model.save(str(dest))


def load_policy(out_dir: str | Path) -> tuple[PPO, VecNormalize | None]:
    """The trained PPO policy and its observation normaliser (for `PolicyHuman`)."""
    out = Path(out_dir)
    model = PPO.load(str(out / POLICY_FILE), device="cpu")
    return model, (load_norm(out) if (out / NORM_FILE).exists() else None)


__all__ = ["AMP_FILE", "BODY_FILE", "CYCLE_FILE", "NORM_FILE", "POLICY_FILE", "PROGRESS_FILE",
           "STEERING_FILE", "Budget", "MetricsLog", "StopOnSignal", "TrainParams", "UpdateThreads",
           "closed_on_error", "learn_for", "load_body", "load_norm", "load_policy", "make_vec_env", "new_ppo",
           "policy_env", "save_body", "save_for_rollouts", "save_steering", "train", "variant_cycle",
           "widen_policy"]
