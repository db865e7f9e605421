"""Evaluation speed: the expert's episodes with every camera rendered, against the same episodes
without images (its own mode), alternating in one run so both see the same machine load."""

from __future__ import annotations

import time

from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode, select
from maniskill_tidy.policies import make_team


def bench_eval(episodes: int = 6, dataset: str | None = None) -> dict:
    cfg = RunConfig("expert", "I", "test", dataset, episodes)
    envs = {images: make_env(cfg, images) for images in (False, True)}
    team = make_team("expert")
    seconds = {False: 0.0, True: 0.0}
    try:
        starts = [e.start for e in envs[False].unwrapped.episodes.episodes]
        chosen = select(starts, episodes)
        for i in chosen:
            for images in (False, True):
                start = time.perf_counter()
                run_episode(envs[images], team, i, i)
                seconds[images] += time.perf_counter() - start
    finally:
        for env in envs.values():
            env.close()
    count = len(chosen)
    return {
        "episodes": count,
        "no_images_s": seconds[False] / count,
        "images_s": seconds[True] / count,
        "ratio": seconds[True] / seconds[False],
    }


def report(r: dict) -> str:
    return (
        "expert evaluation, Setting I test episodes (one worker)\n"
        f"{'episodes':>8} {'s/ep no images':>15} {'s/ep all cameras':>17} {'ratio':>6}\n"
        f"{r['episodes']:>8} {r['no_images_s']:>15.2f} {r['images_s']:>17.2f} {r['ratio']:>6.2f}"
    )
