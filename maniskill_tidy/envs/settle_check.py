"""The dataset check that needs the simulator: every object at rest when an episode starts.

``maniskill-tidy validate --physics`` runs it after the geometric checks of
``tasks/validate.py``; it lives here because it builds the env.
"""

from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.sim.house_scene import MOVED
from maniskill_tidy.tasks.dataset import SPLITS, read_manifest


def physics_problems(
    root: Path, splits: tuple[str, ...] = SPLITS, progress: bool = True
) -> list[str]:
    """Objects that move more than 3 cm while physics settles at the start of an episode.

    Builds every house in the simulator and resets each meta-task once (its starts differ only
    in where the robots stand): slow, about 0.3 s a meta-task on one core."""
    problems = []
    manifest = read_manifest(root)
    for split in splits:
        if not any(n.startswith(split + "/") for n in manifest["files"]):
            continue
        env = HeteroTidyEnv(setting="I", dataset=str(root), split=split, obs_mode="none")
        try:
            firsts = [i for i in range(len(env.episodes)) if env.episodes.get(i).start == 0]
            for i in tqdm(firsts, desc=f"physics {split}", unit="task", disable=not progress):
                _, info = env.reset(options={"episode": i})
                if info["fallen"]:
                    problems.append(
                        f"{env.episode.task.id}: {', '.join(info['fallen'])} moved more than "
                        f"{MOVED * 100:.0f} cm when the episode started (not at rest)"
                    )
        finally:
            env.close()
    return problems
