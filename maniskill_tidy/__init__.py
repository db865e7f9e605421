"""maniskill-tidy: heterogeneous multi-agent tidying-up on ManiSkill3 / SAPIEN.

Importing the package registers ``HeteroTidy-v1`` with gymnasium without importing ManiSkill
(a few seconds); the env module registers itself with ManiSkill's ``register_env`` when it is
first made. ``parallel_env`` gives the PettingZoo view.
"""

from __future__ import annotations

from typing import Any

ENV_ID = "HeteroTidy-v1"
ENTRY_POINT = "maniskill_tidy.envs.hetero_tidy:HeteroTidyEnv"


def register_gym() -> None:
    """(Re-)register ``HeteroTidy-v1`` with gymnasium; truncation is the env's own (300 steps)."""
    import gymnasium as gym

    gym.registry.pop(ENV_ID, None)
    gym.register(ENV_ID, entry_point=ENTRY_POINT)


def parallel_env(**kwargs: Any):
    """A PettingZoo ``ParallelEnv`` of HeteroTidy-v1 (same keyword arguments as the env)."""
    from maniskill_tidy.envs.pettingzoo_env import parallel_env as make

    return make(**kwargs)


register_gym()
