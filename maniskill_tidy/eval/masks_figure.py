"""The pixels track's segmenter at work: agent frames with its classes beside the renderer's.

``maniskill-tidy show-masks --segmenter agents/segmenter-v2 --out masks.png`` plays the first
steps of an episode with the expert (it walks to the misplaced objects), keeps each agent's
frame that shows the most pickupable pixels, and draws per agent: the RGB frame, the renderer's
classes and the segmenter's, pickupable objects named where they are (instances as agents make
them, ``perception/instances.py``), and the object masks a pixels agent would start tracks from
(``policies/pixels.py: find_masks``: what the floor plan does not explain, typed by the
segmenter's votes, and the segmenter's own masks of flat objects).
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from maniskill_tidy.perception.instances import split_instances
from maniskill_tidy.perception.seg_classes import STRUCTURE, seg_classes


def palette() -> np.ndarray:
    """A colour per class: structure in greys, furniture muted, pickupable types bright."""
    c = seg_classes()
    colours = np.zeros((len(c.names), 3))
    for i, name in enumerate(c.names):
        if name in STRUCTURE or name == "robot":
            colours[i] = {"floor": 0.35, "wall": 0.55, "ceiling": 0.75, "robot": 0.95}[name]
        elif name.startswith("furniture:"):
            colours[i] = colorsys.hsv_to_rgb((i * 0.137) % 1.0, 0.35, 0.6)
        elif i:
            colours[i] = colorsys.hsv_to_rgb((i * 0.381) % 1.0, 0.95, 1.0)
    return colours


def overlay(rgb: np.ndarray, labels: np.ndarray, alpha: float = 0.6,
            masked_only: bool = False) -> np.ndarray:  # fmt: skip
    """The frame with each pixel tinted its label's colour (``masked_only``: labels > 0)."""
    a = alpha * (labels > 0)[..., None] if masked_only else alpha
    return (1 - a) * rgb / 255.0 + a * palette()[labels]


def _name_objects(ax, labels: np.ndarray, depth: np.ndarray, masks=None) -> None:
    """Name each object mask above it: ``masks``, else the instances of ``labels``."""
    c = seg_classes()
    pickupable = [i for i in range(len(c.names)) if c.is_pickupable(i)]
    for m in split_instances(labels, depth, pickupable) if masks is None else masks:
        if m.area < 20:
            continue
        rows, cols = np.nonzero(m.mask)
        ax.text(cols.mean(), rows.min() - 2, c.names[m.cls], fontsize=6, color="white",
                ha="center", va="bottom",
                bbox={"facecolor": "black", "alpha": 0.5, "pad": 0.5, "lw": 0})  # fmt: skip


def masks_figure(out: Path, segmenter: str, env_id: str = "HeteroTidy-v2",
                 dataset: str | None = None, split: str = "test", episode: int = 0,
                 steps: int = 40) -> Path:  # fmt: skip
    import gymnasium as gym
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure
    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.models.checkpoints import served_segmenter
    from maniskill_tidy.models.segmenter import upsample
    from maniskill_tidy.perception.object_space import ObjectSpace
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.policies.pixels import find_masks, start_threshold

    runtime, _, card = served_segmenter(segmenter, 2)  # what agents run
    classes = seg_classes()
    env = gym.make(env_id, setting="I", dataset=dataset, split=split,
                   obs_mode="rgb+depth+segmentation")  # fmt: skip
    best: dict[str, tuple] = {}
    try:
        u = env.unwrapped
        obs, info = env.reset(seed=episode, options={"episode": episode})
        name = u.episode.id
        table = classes.lookup(u.instances)
        space = ObjectSpace(u.house)  # the floor plan (objects are not read)
        execution = Execution(make_team("expert"), u, episode)
        for _ in range(steps):
            for agent in u.agent_names:
                o = obs[agent]
                truth = classes.labels(np.asarray(o["segmentation"]).reshape(o["rgb"].shape[:2]),
                                       table)  # fmt: skip
                shown = int((classes.is_pickupable(truth) & (truth > 0)).sum())
                if agent not in best or shown > best[agent][0]:
                    depth = np.asarray(o["depth"], dtype=np.float32).reshape(truth.shape)
                    best[agent] = (shown, np.asarray(o["rgb"]).copy(), depth, truth,
                                   o["intrinsics"], o["extrinsics"])  # fmt: skip
            obs, _, terminated, truncated, info = env.step(execution.step(obs, info))
            if terminated or truncated:
                break
    finally:
        env.close()
    agents = sorted(best)
    threshold = start_threshold(card)
    fig, axes = plt.subplots(len(agents), 4, figsize=(12.8, 3.3 * len(agents)), squeeze=False)
    for r, agent in enumerate(agents):
        _, rgb, depth, truth, K, E = best[agent]
        labels, probs = runtime(rgb[None], depth[None])
        predicted = upsample(labels, probs, depth.shape)[0]
        _, found, starts = find_masks(space, labels[0], probs[0], depth, K, E, threshold)
        found = [m for m, t in zip(found, starts, strict=True) if m.score >= t]
        objects = np.zeros(depth.shape, np.int64)
        for m in found:
            m.paint(objects, m.cls)
        found_img = overlay(rgb, objects, masked_only=True)
        panels = [(rgb / 255.0, None, "RGB"), (overlay(rgb, truth), truth, "renderer's classes"),
                  (overlay(rgb, predicted[0]), predicted[0], "segmenter's classes"),
                  (found_img, found, "objects as agents find them")]  # fmt: skip
        for ax, (img, labels, title) in zip(axes[r], panels, strict=True):
            ax.imshow(img)
            if isinstance(labels, list):
                _name_objects(ax, objects, depth, labels)
            elif labels is not None:
                _name_objects(ax, labels, depth)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(title if r == 0 else "", fontsize=10)
        axes[r, 0].set_ylabel(agent, fontsize=10)
    ap = (card.get("test") or {}).get("AP50")
    score = f", test mask AP50 {ap:.3f}" if ap is not None else ""
    fig.suptitle(f"{name} ({env_id}): {Path(segmenter).name}{score}", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, out, dpi=90)
