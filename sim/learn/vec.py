"""Many envs in few processes: a stable-baselines3 `VecEnv` whose worker processes each step a group
of envs one after the other.

stable-baselines3's `SubprocVecEnv` runs one env per process and exchanges one message per env and
step with each; at 16 processes a walking-env step costs the main process 16 round trips, and env
stepping grew only 3.9x from 1 to 16 processes on a 16-core machine (`sim.learn.throughput`).
Here each of `n_workers` processes holds `n_envs / n_workers` envs and answers one message per
step for all of them, so the envs per core (and the batch the policy sees per step) can grow
without more round trips. Envs auto-reset as in `SubprocVecEnv` (`terminal_observation` in info).
"""

from __future__ import annotations

import multiprocessing as mp
import signal
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper, VecEnv, VecEnvIndices


def _group_worker(remote, parent_remote, fns_wrapper: CloudpickleWrapper) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C: the main process ends the run
    parent_remote.close()
    envs = [fn() for fn in fns_wrapper.var]
    try:
        while True:
            cmd, data = remote.recv()
            if cmd == "step":
                out = []
                for env, action in zip(envs, data, strict=True):
                    obs, reward, terminated, truncated, info = env.step(action)
                    done = terminated or truncated
                    info["TimeLimit.truncated"] = truncated and not terminated
                    reset_info: dict = {}
                    if done:
                        info["terminal_observation"] = obs
                        obs, reset_info = env.reset()
                    out.append((obs, reward, done, info, reset_info))
                remote.send(out)
            elif cmd == "reset":
                remote.send([env.reset(seed=seed, **({"options": opt} if opt else {}))
                             for env, seed, opt in zip(envs, *data, strict=True)])
            elif cmd == "get_spaces":
                remote.send((envs[0].observation_space, envs[0].action_space))
            elif cmd == "get_attr":
                remote.send([envs[i].get_wrapper_attr(data[1]) for i in data[0]])
            elif cmd == "set_attr":
                for i in data[0]:
                    setattr(envs[i], data[1], data[2])
                remote.send(None)
            elif cmd == "env_method":
                remote.send([envs[i].get_wrapper_attr(data[1])(*data[2], **data[3]) for i in data[0]])
            elif cmd == "close":
                for env in envs:
                    env.close()
                remote.close()
                return
            else:
                raise NotImplementedError(cmd)
    except (EOFError, KeyboardInterrupt):
        return


class GroupedSubprocVecEnv(VecEnv):
    """`env_fns` split over `n_workers` processes in contiguous groups (module docstring)."""

    def __init__(self, env_fns: list[Callable[[], gym.Env]], n_workers: int,
                 start_method: str = "fork") -> None:
        n = len(env_fns)
        n_workers = max(1, min(n_workers, n))
        bounds = np.linspace(0, n, n_workers + 1).round().astype(int)
        self.groups = [list(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        ctx = mp.get_context(start_method)
        self.remotes, work = zip(*[ctx.Pipe() for _ in self.groups], strict=True)
        self.processes = []
        for w, r, g in zip(work, self.remotes, self.groups, strict=True):
            proc = ctx.Process(target=_group_worker, args=(w, r, CloudpickleWrapper([env_fns[i] for i in g])),
                               daemon=True)
            proc.start()
            self.processes.append(proc)
            w.close()
        self.remotes[0].send(("get_spaces", None))
        obs_space, act_space = self.remotes[0].recv()
        self.waiting = self.closed = False
        super().__init__(n, obs_space, act_space)

    def step_async(self, actions: np.ndarray) -> None:
        for remote, g in zip(self.remotes, self.groups, strict=True):
            remote.send(("step", [actions[i] for i in g]))
        self.waiting = True

    def step_wait(self):
        results = [r for remote in self.remotes for r in remote.recv()]
        self.waiting = False
        obs, rews, dones, infos, self.reset_infos = zip(*results, strict=True)
        return np.stack(obs), np.array(rews, dtype=np.float32), np.array(dones), list(infos)

    def reset(self):
        for remote, g in zip(self.remotes, self.groups, strict=True):
            remote.send(("reset", ([self._seeds[i] for i in g], [self._options[i] for i in g])))
        results = [r for remote in self.remotes for r in remote.recv()]
        obs, self.reset_infos = zip(*results, strict=True)
        self._reset_seeds()
        self._reset_options()
        return np.stack(obs)

    def close(self) -> None:
        if self.closed:
            return
        if self.waiting:
            for remote in self.remotes:
                remote.recv()
        for remote in self.remotes:
            remote.send(("close", None))
        for proc in self.processes:
            proc.join()
        for remote in self.remotes:
            remote.close()
        self.closed = True

    def _by_worker(self, indices: VecEnvIndices) -> list[tuple[int, list[int]]]:
        """(worker, its local env indices) for the vec indices `indices` (None: every env)."""
        wanted = set(self._get_indices(indices))
        return [(w, [k for k, i in enumerate(g) if i in wanted]) for w, g in enumerate(self.groups)
                if any(i in wanted for i in g)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        targets = self._by_worker(indices)
        for w, local in targets:
            self.remotes[w].send(("get_attr", (local, attr_name)))
        return [x for w, _ in targets for x in self.remotes[w].recv()]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        targets = self._by_worker(indices)
        for w, local in targets:
            self.remotes[w].send(("set_attr", (local, attr_name, value)))
        for w, _ in targets:
            self.remotes[w].recv()

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None,
                   **method_kwargs) -> list:
        targets = self._by_worker(indices)
        for w, local in targets:
            self.remotes[w].send(("env_method", (local, method_name, method_args, method_kwargs)))
        return [x for w, _ in targets for x in self.remotes[w].recv()]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs


__all__ = ["GroupedSubprocVecEnv"]
