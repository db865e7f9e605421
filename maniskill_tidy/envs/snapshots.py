"""Pictures of an episode: each agent's RGB, depth and labelled segmentation, and the house.

``run_episode`` plays one episode with a simple exploring policy (turn, move where the grid
allows, stop at the end) so that a newcomer sees the env work; it is not a tidying policy
(those are in ``policies/``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from maniskill_tidy.common.plotting import plt, save_figure
from maniskill_tidy.envs.actions import Action, move_target
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.envs.registration import ENV_ID, VERSIONS


def views_figure(env: HeteroTidyEnv, obs: dict, title: str, out: Path) -> Path:
    """One row per agent: RGB, depth, segmentation with the largest instances labelled."""
    names = env.agent_names
    fig, axes = plt.subplots(len(names), 3, figsize=(9, 3 * len(names)), squeeze=False)
    for row, name in zip(axes, names, strict=True):
        o = obs[name]
        kind = env.kinds[names.index(name)]
        row[0].imshow(o["rgb"])
        row[0].set_title(f"{name} {kind.name} {tuple(int(v) for v in o['capability'])}", fontsize=8)
        row[1].imshow(o["depth"], cmap="viridis", vmin=0, vmax=8)
        row[1].set_title("depth (m, 0-8)", fontsize=8)
        seg = o["segmentation"]
        ids, counts = np.unique(seg, return_counts=True)
        palette = np.random.default_rng(0).uniform(0.15, 1.0, (int(seg.max()) + 1, 3))
        palette[0] = 0
        row[2].imshow(palette[seg])
        row[2].set_title("instance segmentation", fontsize=8)
        for sid in ids[np.argsort(-counts)][:6]:
            inst = env.instances.get(int(sid))
            if inst is None:
                continue
            v, u = np.nonzero(seg == sid)
            row[2].text(
                u.mean(),
                v.mean(),
                inst.type,
                fontsize=6,
                ha="center",
                color="white",
                bbox={"facecolor": "black", "alpha": 0.5, "pad": 1, "linewidth": 0},
            )
        for ax in row:
            ax.axis("off")
    fig.suptitle(title, fontsize=9)
    return save_figure(fig, out)


def third_person_figure(env: HeteroTidyEnv, title: str, out: Path) -> Path:
    fig, ax = plt.subplots(figsize=(8, 6))
    ax.imshow(env.render())
    ax.set_title(title, fontsize=9)
    ax.axis("off")
    return save_figure(fig, out)


def explore_action(env: HeteroTidyEnv, i: int, rng: np.random.Generator) -> int:
    """Move ahead when the grid allows it, otherwise turn; now and then turn anyway."""
    a = env.agents[i]
    ahead = move_target(a, Action.MoveAhead)
    if env.house.navgrid.free(*ahead) and rng.random() > 0.15:
        return Action.MoveAhead.value
    return int(rng.choice([Action.RotateLeft.value, Action.RotateRight.value]))


def run_episode(
    out: Path,
    setting: str = "I",
    dataset: str | None = None,
    split: str = "test",
    episode: int | str = 0,
    steps: int = 30,
    seed: int = 0,
    env_id: str = ENV_ID,
) -> dict:
    """Play ``steps`` exploring steps, then Stop; write start/end views and the house."""
    out = Path(out)
    env = HeteroTidyEnv(
        setting=setting,
        dataset=dataset,
        split=split,
        render_mode="rgb_array",
        visuals=VERSIONS[env_id],
    )
    rng = np.random.default_rng(seed)
    try:
        obs, info = env.reset(seed=seed, options={"episode": episode})
        head = f"{info['episode']} ({info['task_kind']}, {info['n_misplaced']} misplaced)"
        files = [
            views_figure(env, obs, f"{head}: step 0", out / "agents-step000.png"),
            third_person_figure(env, f"{head}: start", out / "house-start.png"),
        ]
        for _ in range(steps):
            action = {n: explore_action(env, i, rng) for i, n in enumerate(env.agent_names)}
            obs, _, _, _, info = env.step(action)
        files.append(
            views_figure(env, obs, f"{head}: step {steps}", out / f"agents-step{steps:03d}.png")
        )
        files.append(
            third_person_figure(env, f"{head}: after {steps} steps", out / "house-end.png")
        )
        obs, _, terminated, truncated, info = env.step(
            {n: Action.Stop.value for n in env.agent_names}
        )
        failed = sum(len(a.failures) for a in env.agents)
        return {
            "episode": info["episode"],
            "steps": info["steps"],
            "terminated": terminated,
            "failed_actions": failed,
            "files": [str(f) for f in files],
        }
    finally:
        env.close()
