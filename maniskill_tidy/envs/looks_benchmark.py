"""What the v2 look costs: v2 beside v1, and v2 beside its own raw render loop, same run.

Blocks alternate v1 env steps, v2 env steps and two raw SAPIEN loops over the v2 scene: one
drawing every room (the plain reference) and one hiding, per camera, the rooms it cannot see as
the env does (so its ratio is the env's own overhead). Medians over blocks. Memory: resident
set size over many resets across the split's houses.
"""

from __future__ import annotations

import os
import statistics

import numpy as np

from maniskill_tidy.envs.benchmark import NAV_ONLY, env_steps, raw_render_loop, reset_times
from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv


def bench_looks(
    setting: str, quality: str = "fast", blocks: int = 5, steps: int = 40, size: int = 224
) -> dict:
    kw = {"setting": setting, "split": "test", "camera_size": (size, size), "quality": quality}
    v1 = HeteroTidyEnv(**kw)
    v2 = HeteroTidyEnv(**kw, visuals="realistic")
    rng = np.random.default_rng(0)
    rates: dict[str, list[float]] = {"v1": [], "v2": [], "raw": [], "raw_hiding": []}
    try:
        for env in (v1, v2):
            env.reset(options={"episode": 0})
            env_steps(env, 5, rng)  # warm-up: shaders, caches
        for _ in range(blocks):
            rates["v1"].append(env_steps(v1, steps, rng))
            rates["v2"].append(env_steps(v2, steps, rng))
            rates["raw"].append(raw_render_loop(v2, steps))
            rates["raw_hiding"].append(raw_render_loop(v2, steps, hide=True))
        resets = {name: reset_times(env) for name, env in (("v1", v1), ("v2", v2))}
    finally:
        v1.close()
        v2.close()

    def ratio(a: str, b: str) -> float:
        return statistics.median(x / y for x, y in zip(rates[a], rates[b], strict=True))

    return {
        "setting": setting,
        "quality": quality,
        "size": size,
        "hides_rooms": quality == "fast",
        **{f"{k}_per_s": statistics.median(v) for k, v in rates.items()},
        "v2_over_v1": ratio("v2", "v1"),
        "v2_over_raw": ratio("v2", "raw"),
        "v2_over_raw_hiding": ratio("v2", "raw_hiding"),
        **{f"{k}_reset_s": v[0] for k, v in resets.items()},
        **{f"{k}_new_house_s": v[1] for k, v in resets.items()},
    }


def rss_mb() -> float:
    with open(f"/proc/{os.getpid()}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def bench_memory(visuals: str = "realistic", resets: int = 300, every: int = 25) -> dict:
    """RSS after every ``every`` resets, cycling through the split's episodes (new houses)."""
    env = HeteroTidyEnv(setting="I", split="test", visuals=visuals)
    rng = np.random.default_rng(0)
    n = len(env.episodes)
    samples = []
    try:
        for i in range(resets):
            env.reset(options={"episode": (i * 7) % n})
            env.step({a: int(rng.choice(NAV_ONLY)) for a in env.agent_names})
            if (i + 1) % every == 0:
                samples.append(rss_mb())
    finally:
        env.close()
    after_warmup = samples[1:] if len(samples) > 2 else samples
    return {
        "visuals": visuals,
        "resets": resets,
        "rss_mb": samples,
        "growth_mb": after_warmup[-1] - after_warmup[0],
    }


def report(results: list[dict], memory: list[dict]) -> str:
    lines = [
        "looks: v2 (realistic) vs v1 (flat) env steps/s, and v2 vs SAPIEN's raw render loop of",
        "its scene drawing every room (raw) or hiding them as the env does (raw hid.)",
        f"{'setting':>7} {'quality':>7} {'v1/s':>6} {'v2/s':>6} {'v2/v1':>6} {'raw/s':>6} "
        f"{'v2/raw':>6} {'raw hid./s':>10} {'v2/raw hid.':>11} {'reset v1/v2 s':>14} "
        f"{'new house v1/v2 s':>17}",
    ]
    for r in results:
        lines.append(
            f"{r['setting']:>7} {r['quality']:>7} {r['v1_per_s']:>6.1f} {r['v2_per_s']:>6.1f} "
            f"{r['v2_over_v1']:>6.2f} {r['raw_per_s']:>6.1f} {r['v2_over_raw']:>6.2f} "
            f"{r['raw_hiding_per_s']:>10.1f} {r['v2_over_raw_hiding']:>11.2f} "
            f"{r['v1_reset_s']:>6.2f}/{r['v2_reset_s']:<7.2f} "
            f"{r['v1_new_house_s']:>8.2f}/{r['v2_new_house_s']:<8.2f}"
        )
    for m in memory:
        trace = " ".join(f"{v:.0f}" for v in m["rss_mb"])
        lines.append(
            f"RSS {m['visuals']} over {m['resets']} resets (MB every 25): {trace}; "
            f"growth after the first 25: {m['growth_mb']:+.0f} MB"
        )
    return "\n".join(lines)
