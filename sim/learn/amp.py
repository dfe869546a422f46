"""Adversarial motion prior (Peng, Ma, Abbeel, Levine, Kanazawa 2021, ACM TOG 40:144, "AMP").

A discriminator D on consecutive-state features (s, s') learns to tell the subject's reference
motion (+1) from the policy's transitions (-1) with the least-squares GAN loss (Mao et al. 2017)
and a gradient penalty on the reference samples, w_gp / 2 E||grad D||^2 (AMP eq. 8, w_gp = 10).
Its output becomes the style reward r = max(0, 1 - 0.25 (d - 1)^2) (AMP eq. 9).

Settings taken from the public configs: discriminator MLP [1024, 512] with ReLU (IsaacGymEnvs
`HumanoidAMPPPO.yaml`, `disc.units`), input normalisation by running mean / std, and a replay of
the policy's older transitions mixed into the negatives. The [1024, 512] size is a params value
(`train.amp.hidden`); the CPU budget here uses a smaller default, stated in params.yaml.

`AMPCallback` collects `info["amp"]` from every env step of a stable-baselines3 rollout, updates
D once per rollout, adds `w_style x r` to the buffer's rewards and recomputes returns/advantages.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import numpy as np
import torch
from pydantic import Field, with_config
from stable_baselines3.common.callbacks import BaseCallback
from torch import nn


@with_config(extra="forbid")
@dataclass(frozen=True)
class AMPParams:
    """Discriminator settings (params `train.amp`)."""

    hidden: tuple[int, ...] = (256, 256)
    learning_rate: float = 1e-4
    grad_penalty: float = 10.0          # w_gp, AMP eq. 8
    weight_decay: float = 1e-4
    epochs: int = 2                     # passes over each rollout's transitions
    batch_size: int = 512
    replay_size: int = 100000           # older policy transitions kept as negatives
    reward_scale: float = 1.0
    # share of the reference transitions drawn from the subject's whole recorded motion (standing,
    # starting, turning, stopping: `sim.learn.walk_env.motion_amp_pairs`) instead of its cycle
    motion_share: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0


class Discriminator(nn.Module):
    """MLP on normalised transition features; a linear output (no sigmoid: LSGAN)."""

    def __init__(self, n_in: int, hidden: tuple[int, ...]) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        size = n_in
        for h in hidden:
            layers += [nn.Linear(size, h), nn.ReLU()]
            size = h
        layers.append(nn.Linear(size, 1))
        self.net = nn.Sequential(*layers)
        self.register_buffer("mean", torch.zeros(n_in))
        self.register_buffer("var", torch.ones(n_in))
        self.register_buffer("count", torch.tensor(1e-4))

    def update_normaliser(self, x: torch.Tensor) -> None:
        """Running mean / variance (parallel algorithm of Chan et al.)."""
        b_mean, b_var, b_n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta = b_mean - self.mean
        total = self.count + b_n
        self.mean += delta * b_n / total
        self.var = (self.var * self.count + b_var * b_n + delta**2 * self.count * b_n / total) / total
        self.count = total

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = torch.clamp((x - self.mean) / torch.sqrt(self.var + 1e-5), -5.0, 5.0)
        return self.net(z).squeeze(-1)


def style_reward(d: torch.Tensor) -> torch.Tensor:
    """AMP eq. 9: max(0, 1 - 0.25 (d - 1)^2)."""
    return torch.clamp(1.0 - 0.25 * (d - 1.0) ** 2, min=0.0)


class AMP:
    """Discriminator, its optimiser and a replay of policy transitions."""

    def __init__(self, n_in: int, p: AMPParams, reference_sampler: Callable[[int], np.ndarray],
                 seed: int = 0, device: str = "cpu") -> None:
        torch.manual_seed(seed)
        self.p, self.sample_reference, self.device = p, reference_sampler, torch.device(device)
        self.disc = Discriminator(n_in, p.hidden).to(self.device)
        self.opt = torch.optim.Adam(self.disc.parameters(), lr=p.learning_rate, weight_decay=p.weight_decay)
        self.replay = np.zeros((p.replay_size, n_in), np.float32)
        self.replay_n, self.replay_i = 0, 0
        self.rng = np.random.default_rng(seed)

    def _store(self, x: np.ndarray) -> None:
        n = min(len(x), self.p.replay_size)
        idx = (self.replay_i + np.arange(n)) % self.p.replay_size
        self.replay[idx] = x[-n:]
        self.replay_i = int((self.replay_i + n) % self.p.replay_size)
        self.replay_n = min(self.replay_n + n, self.p.replay_size)

    def update(self, policy_x: np.ndarray) -> dict[str, float]:
        """One discriminator update on this rollout's transitions (half fresh, half replayed)."""
        p = self.p
        fresh = self._tensor(policy_x)
        self.disc.update_normaliser(torch.cat([fresh, self._tensor(self.sample_reference(len(policy_x)))]))
        n_batches = max(1, p.epochs * len(policy_x) // p.batch_size)
        stats = torch.zeros(5, device=self.device)  # summed on the device: no sync per batch
        for _ in range(n_batches):
            half = p.batch_size // 2
            neg = policy_x[self.rng.integers(0, len(policy_x), half)]
            if self.replay_n:
                neg = np.vstack([neg, self.replay[self.rng.integers(0, self.replay_n, half)]])
            neg_t = self._tensor(neg)
            pos_t = self._tensor(self.sample_reference(len(neg))).requires_grad_(True)
            d_pos, d_neg = self.disc(pos_t), self.disc(neg_t)
            loss_ls = 0.5 * ((d_pos - 1.0) ** 2).mean() + 0.5 * ((d_neg + 1.0) ** 2).mean()
            grad = torch.autograd.grad(d_pos.sum(), pos_t, create_graph=True)[0]
            gp = (grad**2).sum(-1).mean()
            loss = loss_ls + 0.5 * p.grad_penalty * gp
            self.opt.zero_grad()
            loss.backward()
            self.opt.step()
            stats += torch.stack([loss_ls, gp, (d_pos > 0).float().mean(), (d_neg < 0).float().mean(),
                                  d_pos.mean() - d_neg.mean()]).detach()
        self._store(policy_x)
        s = (stats / n_batches).cpu().numpy()
        return {"disc_loss": s[0], "disc_grad_penalty": s[1], "disc_acc_reference": s[2],
                "disc_acc_policy": s[3], "disc_margin": s[4]}

    def _tensor(self, x: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(x, dtype=torch.float32, device=self.device)

    @torch.no_grad()
    def reward(self, x: np.ndarray) -> np.ndarray:
        d = self.disc(self._tensor(x))
        return (self.p.reward_scale * style_reward(d)).cpu().numpy()

    def state_dict(self) -> dict:
        return {"disc": self.disc.state_dict(), "opt": self.opt.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.disc.load_state_dict(state["disc"])
        self.opt.load_state_dict(state["opt"])


class AMPCallback(BaseCallback):
    """Collects AMP transitions and reward terms during a rollout; at its end updates the
    discriminator, adds `w_style x` style reward to the rollout buffer and recomputes the returns.
    `log(step, metrics)` receives the per-rollout metrics."""

    def __init__(self, amp: AMP, w_style: float, n_terms: int, log: Callable[[int, dict], None]) -> None:
        super().__init__()
        self.amp, self.w_style, self.n_terms, self.log_fn = amp, w_style, n_terms, log
        self.buf: np.ndarray | None = None
        self.terms = np.zeros(n_terms)
        self.n_terms_seen = 0
        self.t = 0
        self.ep_lengths: list[int] = []

    def _on_rollout_start(self) -> None:
        buf = self.model.rollout_buffer
        n_in = self.amp.replay.shape[1]
        if self.buf is None or self.buf.shape[:2] != (buf.buffer_size, buf.n_envs):
            self.buf = np.zeros((buf.buffer_size, buf.n_envs, n_in), np.float32)
        self.t = 0
        self.terms[:] = 0
        self.n_terms_seen = 0
        self.ep_lengths = []

    def _on_step(self) -> bool:
        infos = self.locals["infos"]
        for i, info in enumerate(infos):
            self.buf[self.t, i] = info["amp"]
            self.terms += info["terms"]
            if "episode" in info:
                self.ep_lengths.append(info["episode"]["l"])
        self.n_terms_seen += len(infos)
        self.t += 1
        return True

    def _on_rollout_end(self) -> None:
        buf = self.model.rollout_buffer
        x = self.buf[:self.t].reshape(-1, self.buf.shape[-1])
        stats = self.amp.update(x)
        style = self.amp.reward(x).reshape(self.t, -1)
        buf.rewards[:self.t] += self.w_style * style
        buf.compute_returns_and_advantage(last_values=self.locals["values"], dones=self.locals["dones"])
        metrics = {**stats, "style_reward": float(style.mean()),
                   "rollout_reward": float(buf.rewards[:self.t].mean())}
        names = ("pose", "velocity", "feet", "height", "root_velocity", "task")
        for name, v in zip(names, self.terms / max(self.n_terms_seen, 1), strict=True):
            metrics[f"r_{name}"] = float(v)
        if self.ep_lengths:
            metrics["episode_length"] = float(np.mean(self.ep_lengths))
        self.log_fn(self.num_timesteps, metrics)


__all__ = ["AMP", "AMPCallback", "AMPParams", "Discriminator", "style_reward"]
