"""The env's gymnasium ids, one per look, registered without importing ManiSkill.

``import maniskill_tidy`` calls :func:`register_gym`; the env module registers itself with
ManiSkill's ``register_env`` when it is first made, and registers these again after it.
"""

from __future__ import annotations

ENV_ID = "HeteroTidy-v1"
ENV_V2 = "HeteroTidy-v2"
# The look every command and the PettingZoo view play unless told (``--env``): v2. v1 stays
# for the rows measured in it and for teams whose learned weights read v1's pixels
# (``Team.look``); gymnasium ids are always explicit.
DEFAULT_ENV = ENV_V2
ENTRY_POINT = "maniskill_tidy.envs.hetero_tidy:HeteroTidyEnv"
# An env version is a look: v1 draws flat-coloured primitives, v2 the derived meshes and
# materials (sim/realistic.py). The task, the grid and the segmentation ids are the same.
VERSIONS = {ENV_ID: "flat", ENV_V2: "realistic"}


def register_gym() -> None:
    """(Re-)register both versions with gymnasium; truncation is the env's own (300 steps)."""
    import warnings

    import gymnasium as gym

    # gymnasium calls any id with a higher version "out of date"; v1 is not: the committed
    # rows and the learned teams' weights were made in it (docs/looks.md, "Default")
    warnings.filterwarnings(
        "ignore", message=rf".*The environment {ENV_ID} is out of date", category=DeprecationWarning
    )
    for env_id, visuals in VERSIONS.items():
        gym.registry.pop(env_id, None)
        gym.register(env_id, entry_point=ENTRY_POINT, kwargs={"visuals": visuals})
