"""docs/lighting-before-after.png: v2's agent views lit by the environment map it shipped before
(``--before REV``: mani-skill's ``default.hdr``, no stated origin) and by the one the derivation
paints now (``assets/lighting.py``), with both maps; frames where an agent sees a teammate, so
the modelled robots show too.

    python scripts/lighting_before_after.py --before f26a965~1 --out docs/lighting-before-after.png
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np
import sapien

from maniskill_tidy import assets
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
from maniskill_tidy.sim import environment_map


def teammate_frames(setting: str, want: int, episodes: range) -> list[tuple[int, int, str]]:
    """(episode, step, agent) of starts where an agent's camera sees another robot's body."""
    env = HeteroTidyEnv(setting=setting, split="test", visuals="realistic")
    found = []
    try:
        for ep in episodes:
            obs, _ = env.reset(options={"episode": ep})
            robots = {e.per_scene_id: n for n, e in zip(env.agent_names, env.robots, strict=True)}
            for name in env.agent_names:
                ids, counts = np.unique(obs[name]["segmentation"], return_counts=True)
                seen = [robots[i] for i, c in zip(ids, counts, strict=True)
                        if i in robots and robots[i] != name and c > 600]  # fmt: skip
                if seen:
                    found.append((ep, 0, name))
                    break
            if len(found) == want:
                break
    finally:
        env.close()
    return found


def views(frames, setting: str, hdr: Path) -> list[np.ndarray]:
    environment_map.cubemap.cache_clear()
    original = environment_map.cubemap
    environment_map.cubemap = lambda: sapien.render.RenderCubemap(str(hdr))
    env = HeteroTidyEnv(setting=setting, split="test", visuals="realistic")
    try:
        out = []
        for ep, _, name in frames:
            obs, _ = env.reset(options={"episode": ep})
            out.append(obs[name]["rgb"])
        return out
    finally:
        env.close()
        environment_map.cubemap = original


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", required=True, help="a commit whose environment.hdr was the old")
    p.add_argument("--out", default="docs/lighting-before-after.png")
    p.add_argument("--setting", default="II")
    args = p.parse_args()
    rel = "maniskill_tidy/assets/data/environment.hdr"
    old = subprocess.run(["git", "show", f"{args.before}:{rel}"], capture_output=True, check=True)
    tmp = Path(tempfile.mkdtemp()) / "before.hdr"
    tmp.write_bytes(old.stdout)
    new = assets.path("environment.hdr")
    frames = teammate_frames(args.setting, 4, range(60))
    rows = [("before: default.hdr (mani-skill, origin unstated)", tmp),
            ("now: assets/lighting.py (painted by the derivation)", new)]  # fmt: skip

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1 + len(frames), figsize=(3.1 * (1 + len(frames)), 6.4))
    pictures = [views(frames, args.setting, hdr) for _, hdr in rows]
    for r, (label, hdr) in enumerate(rows):
        latlong = cv2.imread(str(hdr), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)[..., ::-1]
        axes[r, 0].imshow(latlong.clip(0, 1))
        axes[r, 0].set_title(label, fontsize=8)
        for c, (ep, _, name) in enumerate(frames, start=1):
            before, now = pictures[0][c - 1], pictures[1][c - 1]
            axes[r, c].imshow(pictures[r][c - 1])
            diff = np.abs(now.astype(int) - before.astype(int)).mean()
            means = f"mean {now.mean():.0f} vs {before.mean():.0f}"
            title = f"test episode {ep}, {name}" if r == 0 else (
                f"|now - before| {diff:.1f} of 255 per pixel; {means}")
            axes[r, c].set_title(title, fontsize=8)
        for ax in axes[r]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle(f"HeteroTidy-v2, Setting {args.setting}: the environment map before and after "
                 "(left: the map as a lat-long image, clipped to [0, 1] as svulkan2 reads it)",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}: frames {frames}")


if __name__ == "__main__":
    main()
