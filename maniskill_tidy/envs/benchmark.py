"""Env throughput next to the raw SAPIEN render loop of the same scene and cameras.

The reference loop does only what no env can avoid: ``update_render`` and, per agent camera,
``take_picture`` and the two textures the observation needs (colour; position + segmentation).
Env and reference run in alternating blocks on the same scene, so load on the shared machine
hits both alike; the ratio is the median over blocks.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv

NAV_ONLY = [a.value for a in Action if a.value < Action.Stop]  # keeps every agent going


def raw_render_loop(env: HeteroTidyEnv, frames: int, hide: bool = False) -> float:
    """Frames (all agent cameras) per second of plain SAPIEN on the env's scene; ``hide``:
    each camera with the rooms it cannot see hidden, as the v2 env does."""
    scene = env.scene.sub_scenes[0]
    cams = [env._agent_camera(name) for name in env.agent_names]
    start = time.perf_counter()
    for _ in range(frames):
        scene.update_render()
        if hide:
            env._take_pictures(dict(zip(env.agent_names, cams, strict=True)))
        for cam in cams:
            if not hide:
                cam.take_picture()
            cam.get_picture("Color")
            cam.get_picture("PositionSegmentation")
    return frames / (time.perf_counter() - start)


def env_steps(env: HeteroTidyEnv, steps: int, rng: np.random.Generator) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        action = {n: int(rng.choice(NAV_ONLY)) for n in env.agent_names}
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset(options={"episode": 0})
    return steps / (time.perf_counter() - start)


def bench_env(
    setting: str, blocks: int = 5, steps: int = 40, size: int = 224, quality: str = "fast"
) -> dict:
    env = HeteroTidyEnv(setting=setting, split="test", camera_size=(size, size), quality=quality)
    rng = np.random.default_rng(0)
    try:
        env.reset(options={"episode": 0})
        env_steps(env, 5, rng)  # warm-up
        raw_render_loop(env, 5)
        env_rates, raw_rates = [], []
        for _ in range(blocks):
            env_rates.append(env_steps(env, steps, rng))
            raw_rates.append(raw_render_loop(env, steps))
        ratios = [e / r for e, r in zip(env_rates, raw_rates, strict=True)]
        same, other = reset_times(env)
    finally:
        env.close()
    return {
        "setting": setting,
        "quality": quality,
        "agents": len(env.agent_names),
        "size": size,
        "env_steps_per_s": statistics.median(env_rates),
        "raw_frames_per_s": statistics.median(raw_rates),
        "ratio": statistics.median(ratios),
        "reset_same_house_s": same,
        "reset_new_house_s": other,
    }


def reset_times(env: HeteroTidyEnv, repeats: int = 5) -> tuple[float, float]:
    """Median seconds to reset to another task of the same house, and to a new house."""
    episodes = env.episodes.episodes
    first = episodes[0].house_id
    same = [i for i, e in enumerate(episodes) if e.house_id == first][1 : repeats + 1]
    other = next(i for i, e in enumerate(episodes) if e.house_id != first)
    same_t, new_t = [], []
    for i in same:
        env.reset(options={"episode": 0})
        start = time.perf_counter()
        env.reset(options={"episode": i})
        same_t.append(time.perf_counter() - start)
    for k in range(repeats):
        start = time.perf_counter()
        env.reset(options={"episode": other if k % 2 == 0 else 0})
        new_t.append(time.perf_counter() - start)
    return statistics.median(same_t), statistics.median(new_t)


def report(results: list[dict]) -> str:
    lines = [
        "env step (all agents act, RGB + depth + segmentation per agent) vs raw SAPIEN render loop",
        f"{'setting':>7} {'quality':>7} {'agents':>6} {'size':>5} {'steps/s':>8} "
        f"{'raw fps':>8} {'ratio':>6} {'reset s':>8} {'new house s':>11}",
    ]
    for r in results:
        lines.append(
            f"{r['setting']:>7} {r['quality']:>7} {r['agents']:>6} {r['size']:>5} "
            f"{r['env_steps_per_s']:>8.1f} {r['raw_frames_per_s']:>8.1f} {r['ratio']:>6.2f} "
            f"{r['reset_same_house_s']:>8.3f} {r['reset_new_house_s']:>11.3f}"
        )
    return "\n".join(lines)
