"""Where ``demos --features`` spends a trajectory (issue 48).

    python scripts/profile_demos.py [--env HeteroTidy-v2] [--houses 2] [--top 30]

cProfile of the first meta-task's first start of ``--houses`` train houses (one process, as
``bench --only teams`` times it; the agents' readers on its one thread), then the split: the
env's steps (cameras drawn), the expert's privileged previews, the agents' readers (maps and
inputs), resets and house building, the rest. Nothing is kept: the demos go to a temporary
folder.
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

# (label, file suffix, function name) of the calls the split names
PARTS = (
    ("env steps (cameras drawn)", "envs/hetero_tidy.py", "step"),
    ("expert previews", "envs/hetero_tidy.py", "preview"),
    ("agents' readers", "perception/frame_inputs.py", "read"),
    ("resets (houses built)", "envs/hetero_tidy.py", "reset"),
)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--houses", type=int, default=2)
    p.add_argument("--top", type=int, default=30)
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
    n = m["trajectories"]
    print(f"demos --features on {args.env}: {n} trajectories, {wall:.1f} s (profiled)")
    cumulative = {
        (file, name): entry[3]
        for (file, _, name), entry in stats.stats.items()  # type: ignore[attr-defined]
    }
    named = 0.0
    for label, suffix, name in PARTS:
        seconds = sum(t for (f, fn), t in cumulative.items() if f.endswith(suffix) and fn == name)
        named += seconds
        print(f"{seconds / n:8.2f} s/trajectory  {label}")
    print(f"{(wall - named) / n:8.2f} s/trajectory  the rest (start-up, the expert, writing)")


if __name__ == "__main__":
    main()
