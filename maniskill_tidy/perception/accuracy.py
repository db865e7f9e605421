"""How well a look-around map matches the house spec: obstacle IoU over the explored cells of
the start room, per camera height. The map tests assert on it; ``python -m maniskill_tidy.bench
--only map-accuracy`` reports it over 20 test episodes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from matplotlib.path import Path as PolygonPath

from maniskill_tidy.houses.schema import House
from maniskill_tidy.perception.look_around import look_around
from maniskill_tidy.perception.map_grid import EXPLORED, MapFrame
from maniskill_tidy.perception.map_truth import ground_truth_obstacles, obstacle_iou
from maniskill_tidy.perception.semantic_map import SemanticMap
from maniskill_tidy.tasks.metatask import apply_task

SURVEY_TEAM = [[1, 0, 0], [1, 1, 1], [1, 0, 1]]  # low scout (0.22 m camera), manipulator, high
CAMERAS = {"agent_0": "low", "agent_1": "high", "agent_2": "high"}


def messy_house(env) -> House:
    """The house spec with the episode's objects where the task put them."""
    return apply_task(env.hs.house, env.episode.task)


def room_cells(house: House, frame: MapFrame, x: float, y: float) -> np.ndarray:
    """(rows, cols) bool: map cells inside the room that contains (x, y)."""
    room = house.room(house.room_at(x, y))
    r, c = np.mgrid[0 : frame.shape[0], 0 : frame.shape[1]]
    inside = PolygonPath(room.polygon).contains_points(frame.centres(r, c).reshape(-1, 2))
    return inside.reshape(frame.shape)


def start_room_iou(m: SemanticMap, house: House, start: tuple[float, float]) -> float:
    td = m.top_down()
    region = room_cells(house, m.frame, *start) & (td[..., EXPLORED] > 0)
    return obstacle_iou(td, ground_truth_obstacles(house, m.frame), region)


def survey_iou(env, episodes) -> dict[str, list[float]]:
    """Start-room IoU of every agent's look-around map, per camera ("low", "high").
    ``env`` is an unwrapped HeteroTidy env with images and the ``SURVEY_TEAM``."""
    out: dict[str, list[float]] = {"low": [], "high": []}
    for episode in episodes:
        for agent in env.agent_names:
            obs, _ = env.reset(seed=0, options={"episode": episode})
            state = env.agents[env.agent_names.index(agent)]
            start = env.house.navgrid.center(*state.cell)
            m = look_around(env, agent, obs)
            out[CAMERAS[agent]].append(start_room_iou(m, messy_house(env), start))
    return out


def bench_map_accuracy(episodes: int = 20) -> dict[str, dict[str, float]]:
    env = gym.make(
        "HeteroTidy-v1", obs_mode="rgb+depth+segmentation", setting=SURVEY_TEAM, split="test"
    )
    try:
        ious = survey_iou(env.unwrapped, range(episodes))
    finally:
        env.close()
    return {
        camera: {
            "rooms": len(v),
            "mean": float(np.mean(v)),
            "p10": float(np.percentile(v, 10)),
            "min": float(np.min(v)),
        }
        for camera, v in ious.items()
    }


def report(r: dict) -> str:
    lines = [
        "obstacle IoU after a look-around, explored cells of the start room (house spec truth)",
        f"{'camera':>6} {'rooms':>6} {'mean':>6} {'p10':>6} {'min':>6}",
    ]
    for camera, v in r.items():
        lines.append(
            f"{camera:>6} {v['rooms']:>6} {v['mean']:>6.3f} {v['p10']:>6.3f} {v['min']:>6.3f}"
        )
    return "\n".join(lines)
