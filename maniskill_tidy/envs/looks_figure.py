"""The v1 / v2 comparison picture: one episode, both looks, agent views and the house."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv


def looks_figure(
    out: Path, dataset: str | None = None, split: str = "test", episode: int = 0
) -> Path:
    """Two rows (v1, v2): the third-person view, then each agent's RGB after a LookUp
    and a LookDown (the ceiling and the floor ahead)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = []
    for visuals in ("flat", "realistic"):
        env = HeteroTidyEnv(
            setting="I", dataset=dataset, split=split, visuals=visuals, render_mode="rgb_array"
        )
        try:
            obs, info = env.reset(options={"episode": episode})
            level = [obs[n]["rgb"] for n in env.agent_names]
            up, *_ = env.step({n: int(Action.LookUp) for n in env.agent_names})
            rows.append((visuals, env.render(), level, [up[n]["rgb"] for n in env.agent_names]))
            name = info["episode"]
        finally:
            env.close()
    n = len(rows[0][2])
    fig, axes = plt.subplots(2, 1 + 2 * n, figsize=(3 * (1 + 2 * n), 6.6))
    for r, (visuals, top, level, up) in enumerate(rows):
        label = {"flat": "HeteroTidy-v1", "realistic": "HeteroTidy-v2"}[visuals]
        images = [top, *level, *up]
        titles = ["house", *[f"agent_{i}" for i in range(n)], *[f"agent_{i} up" for i in range(n)]]
        for c, (img, title) in enumerate(zip(images, titles, strict=True)):
            ax = axes[r, c]
            ax.imshow(np.asarray(img))
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(title if r == 0 else "", fontsize=9)
            if c == 0:
                ax.set_ylabel(label, fontsize=11)
    fig.suptitle(f"{name}: the same episode in both looks (agent cameras 224 px)", fontsize=11)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    fig.savefig(tmp, dpi=90)
    plt.close(fig)
    tmp.replace(out)
    return out
