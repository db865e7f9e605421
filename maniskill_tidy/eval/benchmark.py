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


def bench_throughput(episodes: int = 8, dataset: str | None = None) -> list[dict]:
    """Episodes per hour of `eval` with 1 and 2 local processes and 2 actors on a local Ray
    instance: the expert on the same Setting I test episodes, every camera rendered (as a
    camera-only team renders them). Wall time from the call to the summary, so the Ray row
    pays for starting Ray and its actors, as a user's run does."""
    import tempfile
    from pathlib import Path

    from maniskill_tidy.eval.runner import evaluate

    cfg = RunConfig("expert", "I", "test", dataset, episodes)
    rows = []
    for workers, ray in ((1, None), (2, None), (2, "local")):
        with tempfile.TemporaryDirectory(prefix="bench-eval-") as out:
            start = time.perf_counter()
            summary = evaluate(cfg, Path(out), workers, progress=False, images=True, ray=ray)
            seconds = time.perf_counter() - start
        rows.append(
            {
                "backend": "Ray (local)" if ray else "processes",
                "workers": workers,
                "episodes": summary["episodes"],
                "seconds": seconds,
                "episodes_per_hour": summary["episodes"] / seconds * 3600,
            }
        )
    for r in rows:
        r["ratio"] = r["episodes_per_hour"] / rows[0]["episodes_per_hour"]
    return rows


def report_throughput(rows: list[dict]) -> str:
    lines = [
        "evaluation throughput: expert, Setting I test, every camera rendered",
        f"{'backend':>12} {'workers':>7} {'episodes':>8} {'s':>7} {'ep/h':>7} {'ratio':>6}",
    ]
    for r in rows:
        lines.append(
            f"{r['backend']:>12} {r['workers']:>7} {r['episodes']:>8} {r['seconds']:>7.1f} "
            f"{r['episodes_per_hour']:>7.0f} {r['ratio']:>6.2f}"
        )
    return "\n".join(lines)
