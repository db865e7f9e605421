"""Pictures of semantic maps: an RGB rendering (for PNGs and the rerun recording) and the
``maniskill-tidy show-map`` figure of one agent's map after a scripted look-around."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.perception.crops import egocentric_crop
from maniskill_tidy.perception.map_grid import EXPLORED, FIRST_CHANNEL, OBSTACLE
from maniskill_tidy.perception.map_truth import ground_truth_obstacles, obstacle_iou
from maniskill_tidy.perception.semantic_map import SemanticMap
from maniskill_tidy.sim.appearance import hashed_colour

UNEXPLORED, FREE, BLOCKED = (255, 255, 255), (222, 222, 222), (95, 95, 95)


def category_colours(categories: tuple[str, ...]) -> np.ndarray:
    """(K, 3) uint8: a stable colour per category, objects more saturated than furniture."""
    small = set(load_catalog().pickupable)
    out = []
    for name in categories:
        rgb = np.array(hashed_colour(name)) * 255
        out.append(rgb if name in small else 0.55 * rgb + 0.45 * 255)
    return np.array(out, dtype=np.uint8)


def top_category(top_down: np.ndarray, categories: tuple[str, ...]) -> np.ndarray:
    """(rows, cols) index of the category shown per cell (objects over furniture), -1 if none."""
    small = set(load_catalog().pickupable)
    weight = np.array([2 if n in small else 1 for n in categories], dtype=np.uint8)
    score = top_down[..., FIRST_CHANNEL:] * weight
    best = score.argmax(axis=-1)
    return np.where(score.max(axis=-1) > 0, best, -1)


UNEXPLORED_CLASS, FREE_CLASS, OBSTACLE_CLASS, FIRST_CATEGORY_CLASS = 0, 1, 2, 3


def map_classes(top_down: np.ndarray, categories: tuple[str, ...]) -> np.ndarray:
    """(rows, cols) uint8 class per cell, map order: 0 unexplored, 1 free, 2 obstacle,
    3 + k category k (the shown one, as in :func:`map_rgb`)."""
    out = np.full(top_down.shape[:2], UNEXPLORED_CLASS, dtype=np.uint8)
    out[top_down[..., EXPLORED] > 0] = FREE_CLASS
    out[top_down[..., OBSTACLE] > 0] = OBSTACLE_CLASS
    best = top_category(top_down, categories)
    out[best >= 0] = FIRST_CATEGORY_CLASS + best[best >= 0]
    return out


def class_legend(categories: tuple[str, ...]) -> list[tuple[int, str, tuple[int, int, int]]]:
    """(class id, label, colour) of every value :func:`map_classes` can take."""
    colours = category_colours(categories)
    return [
        (UNEXPLORED_CLASS, "unexplored", UNEXPLORED),
        (FREE_CLASS, "explored, free", FREE),
        (OBSTACLE_CLASS, "obstacle", BLOCKED),
    ] + [
        (FIRST_CATEGORY_CLASS + i, name, tuple(int(v) for v in colours[i]))
        for i, name in enumerate(categories)
    ]


def map_rgb(top_down: np.ndarray, categories: tuple[str, ...]) -> np.ndarray:
    """(rows, cols, 3) uint8 in map order (row 0 is the south edge): unexplored white, free
    light grey, obstacles dark grey, categories in their colours."""
    image = np.empty(top_down.shape[:2] + (3,), dtype=np.uint8)
    image[:] = UNEXPLORED
    image[top_down[..., EXPLORED] > 0] = FREE
    image[top_down[..., OBSTACLE] > 0] = BLOCKED
    best = top_category(top_down, categories)
    shown = best >= 0
    image[shown] = category_colours(categories)[best[shown]]
    return image


def draw_map(
    semantic: SemanticMap, out: Path, pose, house=None, title: str | None = None
) -> tuple[Path, float | None]:
    """The map with frontiers and the agent, the egocentric crop beside it; with ``house``
    the spec's obstacles are outlined and the obstacle IoU over explored cells returned."""
    import matplotlib.patches as mpatches
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    td = semantic.top_down()
    frame = semantic.frame
    x0, y0 = frame.origin
    extent = (x0, x0 + frame.shape[1] * frame.cell, y0, y0 + frame.shape[0] * frame.cell)
    fig, (ax, ax_crop) = plt.subplots(
        1, 2, figsize=(13, 6.5), gridspec_kw={"width_ratios": [2.2, 1]}
    )
    ax.imshow(map_rgb(td, semantic.categories), origin="lower", extent=extent)
    iou = None
    if house is not None:
        truth = ground_truth_obstacles(house, frame)
        ax.contour(
            truth.astype(float),
            levels=[0.5],
            colors="#1565c0",
            linewidths=0.7,
            origin="lower",
            extent=extent,
        )
        iou = obstacle_iou(td, truth, td[..., EXPLORED] > 0)
    for f in semantic.frontiers():
        xy = frame.centres(f.cells[:, 0], f.cells[:, 1])
        ax.scatter(xy[:, 0], xy[:, 1], s=2, c="#e53935", marker="s", linewidths=0)
        ax.plot(*f.centroid, "x", color="#b71c1c", ms=8, mew=2)
    x, y, rotation = (float(v) for v in pose)
    yaw = math.radians(rotation)
    ax.arrow(x, y, 0.35 * math.cos(yaw), 0.35 * math.sin(yaw), width=0.06, color="#d81b60")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    best = top_category(td, semantic.categories)
    present = [i for i in np.unique(best) if i >= 0]
    colours = category_colours(semantic.categories)
    handles = [
        mpatches.Patch(color=np.array(BLOCKED) / 255, label="obstacle"),
        mpatches.Patch(color=np.array(FREE) / 255, label="explored, free"),
        mpatches.Patch(color="#e53935", label="frontier (x: target)"),
    ]
    if house is not None:
        handles.append(mpatches.Patch(color="#1565c0", label="house spec obstacles", fill=False))
    handles += [
        mpatches.Patch(color=colours[i] / 255, label=semantic.categories[i]) for i in present
    ]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7)
    heading = f" - obstacle IoU {iou:.3f} (explored cells)" if iou is not None else ""
    ax.set_title((title or "semantic map") + heading, fontsize=10)
    crop = egocentric_crop(td, frame, pose, semantic.config.crop_size, semantic.config.crop_cell)
    ax_crop.imshow(map_rgb(crop, semantic.categories))
    n = semantic.config.crop_size
    ax_crop.plot((n - 1) / 2, (n - 1) / 2, "^", color="#d81b60", ms=10)
    ax_crop.set_title(
        f"egocentric crop {n}x{n} x {semantic.channels} at {semantic.config.crop_cell} m "
        "(up = ahead)",
        fontsize=9,
    )
    ax_crop.set_xticks([])
    ax_crop.set_yticks([])
    return save_figure(fig, out), iou


def show_map(
    out: Path,
    setting: str = "I",
    dataset: str | None = None,
    split: str = "test",
    episode: int | str = 0,
    agent: str = "agent_0",
    horizons: tuple[int, ...] | None = None,
    env_id: str = "HeteroTidy-v1",
) -> dict:
    """Reset the env to an episode, let ``agent`` look around, draw its map."""
    import gymnasium as gym

    from maniskill_tidy.perception.look_around import LOOK_AROUND_HORIZONS, look_around
    from maniskill_tidy.tasks.metatask import apply_task

    env = gym.make(
        env_id,
        obs_mode="rgb+depth+segmentation",
        setting=setting,
        dataset=dataset,
        split=split,
    )
    try:
        u = env.unwrapped
        obs, _ = u.reset(seed=0, options={"episode": episode})
        semantic = look_around(u, agent, obs, horizons or LOOK_AROUND_HORIZONS)
        state = u.agents[u.agent_names.index(agent)]
        x, y = u.house.navgrid.center(*state.cell)
        messy = apply_task(u.hs.house, u.episode.task)
        kind = u.kinds[u.agent_names.index(agent)]
        title = f"{u.episode.id} {agent} ({kind.name}, camera {kind.camera_height} m)"
        path, iou = draw_map(semantic, Path(out), (x, y, state.rotation), messy, title)
    finally:
        env.close()
    return {
        "out": str(path),
        "frames": semantic.frames,
        "iou": iou,
        "frontiers": len(semantic.frontiers()),
        "title": title,
    }
