"""How long loading a dataset split and listing its episodes take, with Python's cycle
collector running and paused (issue 48; ``common/memory.py``).

    python docs/research/probes/load_probe.py [--dataset data/tidy120] [--split train] [--rounds 3]

In a process that has imported what a command has (torch, SAPIEN, ManiSkill), whose objects
every collection walks. Prints the median of alternating rounds. Nothing is written.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import statistics
import time
from pathlib import Path
from unittest import mock

import maniskill_tidy.envs  # noqa: F401  (ManiSkill, SAPIEN, torch: what a command has loaded)
from maniskill_tidy.common.memory import collector_paused
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.tasks.dataset import load_dataset


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--split", default="train")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    root = Path(args.dataset)
    jobs = {
        "load_dataset": lambda: load_dataset(root, args.split),
        "EpisodeSet.for_setting": lambda: EpisodeSet.for_setting(root, args.split, "I"),
    }
    pauses = {"collector running": contextlib.nullcontext, "collector paused": collector_paused}
    times: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.rounds):
        for name, job in jobs.items():
            for mode, pause in pauses.items():
                with (
                    mock.patch("maniskill_tidy.tasks.dataset.collector_paused", pause),
                    mock.patch("maniskill_tidy.envs.episodes.collector_paused", pause),
                ):
                    gc.collect()
                    start = time.perf_counter()
                    job()
                    times.setdefault((name, mode), []).append(time.perf_counter() - start)
    print(f"{args.dataset} {args.split}, median of {args.rounds} rounds, seconds")
    for (name, mode), seconds in times.items():
        print(f"{name:<24}{mode:<20}{statistics.median(seconds):8.3f}")


if __name__ == "__main__":
    main()
