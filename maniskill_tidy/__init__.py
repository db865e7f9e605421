"""maniskill-tidy: heterogeneous multi-agent tidying-up on ManiSkill3 / SAPIEN.

Importing the package registers ``HeteroTidy-v1`` (the flat look) and ``HeteroTidy-v2`` (the
realistic look) with gymnasium without importing ManiSkill (a few seconds); the env module
registers itself with ManiSkill's ``register_env`` when it is first made. ``parallel_env`` gives
the PettingZoo view of either.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import Any

from maniskill_tidy.envs.registration import DEFAULT_ENV, ENV_ID, ENV_V2, VERSIONS, register_gym

__all__ = [
    "DEFAULT_ENV",
    "ENV_ID",
    "ENV_V2",
    "VERSIONS",
    "__version__",
    "parallel_env",
    "register_gym",
]

try:
    __version__ = version("maniskill-tidy")
except PackageNotFoundError:  # a source tree on sys.path, not installed
    __version__ = "0+unknown"


def parallel_env(**kwargs: Any):
    """A PettingZoo ``ParallelEnv`` of the env in the default look, v2 (its keyword arguments;
    ``env_id="HeteroTidy-v1"`` for the flat one, where the PettingZoo module takes it)."""
    from maniskill_tidy.envs.pettingzoo_env import parallel_env as make

    return make(**kwargs)


register_gym()
