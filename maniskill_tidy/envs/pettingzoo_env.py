"""A PettingZoo view of HeteroTidy-v1 and -v2: one agent per robot, made as PettingZoo's own
envs are.

``parallel_env(setting="I")`` gives a ``ParallelEnv`` of the default look (v2,
``DEFAULT_ENV``), ``parallel_env(env_id="HeteroTidy-v1")`` one of v1; ``env(...)`` its AEC
conversion. The team shares one reward (the change in misplaced objects at reasonable places).
An agent that chose ``Stop`` is terminated and leaves ``agents``; when the step limit truncates
the episode every remaining agent is truncated.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.envs.registration import DEFAULT_ENV, VERSIONS


class HeteroTidyParallelEnv(ParallelEnv):
    metadata = {"name": "hetero_tidy_v2", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(
        self, render_mode: str | None = None, env_id: str = DEFAULT_ENV, **kwargs: Any
    ) -> None:
        if env_id not in VERSIONS:
            raise ValueError(f"env_id {env_id!r}: expected one of {sorted(VERSIONS)}")
        kwargs.setdefault("visuals", VERSIONS[env_id])
        self.env = HeteroTidyEnv(render_mode=render_mode, **kwargs)
        self.metadata = {**self.metadata, "name": env_id.lower().replace("-", "_")}
        self.render_mode = render_mode
        self.possible_agents = list(self.env.agent_names)
        self.agents = list(self.possible_agents)

    def observation_space(self, agent: str):
        return self.env.observation_space[agent]

    def action_space(self, agent: str):
        return self.env.action_space[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.agents = list(self.possible_agents)
        return obs, {a: dict(info) for a in self.agents}

    def step(self, actions: dict[str, Any]):
        live = list(self.agents)
        obs, reward, terminated, truncated, info = self.env.step(actions)
        stopped = info["stopped"]
        terminations = {a: bool(stopped[a]) for a in live}
        truncations = {a: bool(truncated) and not stopped[a] for a in live}
        rewards = {a: float(reward) for a in live}
        infos = {a: dict(info) for a in live}
        observations = {a: obs[a] for a in live}
        self.agents = [a for a in live if not (terminations[a] or truncations[a])]
        return observations, rewards, terminations, truncations, infos

    def render(self) -> np.ndarray | None:
        return self.env.render() if self.render_mode else None

    def close(self) -> None:
        self.env.close()

    def state(self) -> np.ndarray:
        """The global view: the third-person image of the house."""
        return self.env.render_rgb_array()[0].cpu().numpy()


def parallel_env(**kwargs: Any) -> HeteroTidyParallelEnv:
    return HeteroTidyParallelEnv(**kwargs)


def env(**kwargs: Any):
    return parallel_to_aec(parallel_env(**kwargs))
