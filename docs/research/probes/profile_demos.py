"""Where ``demos --features`` spends a trajectory (issue 48).

    python docs/research/probes/profile_demos.py [--env HeteroTidy-v2] [--houses 2] [--top 30] \
        [--callers REGEX]

cProfile of the first meta-task's first start of ``--houses`` train houses (one process, as
``bench --only teams`` times it; the agents' readers on its one thread), then the split: the
env's steps (cameras drawn), the expert's privileged previews, the agents' readers (maps and
inputs), resets and house building, the rest. Nothing is kept: the demos go to a temporary
folder. ``--callers`` adds who called the functions whose names match (``gc.collect``).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import tempfile
import time
from pathlib import Path

from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features

# (label, file suffix, function name) of the calls the split names; a reset inside the env's
# constructor (ManiSkill's first one, with the first render of the process) counts as
# making the env, not as an episode's reset
PARTS = (
    ("making the env (set-up, first render)", "envs/hetero_tidy.py", "__init__"),
    ("env steps (cameras drawn)", "envs/hetero_tidy.py", "step"),
    ("expert previews", "envs/hetero_tidy.py", "preview"),
    ("agents' readers", "perception/frame_inputs.py", "read"),
    ("episode resets (scene rebuilt)", "envs/hetero_tidy.py", "reset"),
)


def seconds_in(stats: pstats.Stats, suffix: str, name: str) -> float:
    """Cumulative seconds of ``name`` in a file ending in ``suffix``, less what a constructor
    called of it."""
    total = 0.0
    for (file, _, fn), (_, _, _, seconds, callers) in stats.stats.items():  # type: ignore[attr-defined]
        if file.endswith(suffix) and fn == name:
            made = sum(c[3] for (_, _, caller), c in callers.items() if caller == "__init__")
            total += seconds - (made if name != "__init__" else 0.0)
    return total


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--houses", type=int, default=2)
    p.add_argument("--top", type=int, default=30)
    p.add_argument("--callers", help="regex of functions whose callers to print")
    args = p.parse_args()
    os.environ["TIDY_AGENT_THREADS"] = "1"  # cProfile sees only its own thread
    cfg = DemoConfig("I", "train", starts=1, tasks=1, houses=args.houses, env=args.env)
    profile = cProfile.Profile()
    with tempfile.TemporaryDirectory(prefix="profile-demos-") as out:
        start = time.perf_counter()
        profile.enable()
        m = build_demo_features(Path(out), args.dataset, cfg, workers=1, progress=False)
        profile.disable()
        wall = time.perf_counter() - start
    stats = pstats.Stats(profile)
    stats.sort_stats("tottime").print_stats(args.top)
    if args.callers:
        stats.print_callers(args.callers)
    n = m["trajectories"]
    print(f"demos --features on {args.env}: {n} trajectories, {wall:.1f} s (profiled)")
    named = 0.0
    for label, suffix, name in PARTS:
        seconds = seconds_in(stats, suffix, name)
        named += seconds
        print(f"{seconds / n:8.2f} s/trajectory  {label}")
    print(f"{(wall - named) / n:8.2f} s/trajectory  the rest (imports, the expert, writing)")


if __name__ == "__main__":
    main()
