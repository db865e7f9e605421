"""What the pixels-team probes share: their command line (a camera-only team, the dataset, the
segmenter, how many Setting I test episodes in v2) and the loop that plays each episode with a
fresh observer."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, make_run_team, select


def arguments(doc: str, policy: str, episodes: int) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--policy", default=policy)
    ap.add_argument("--dataset", default="data/tidy120")
    ap.add_argument("--segmentation", default="learned")
    ap.add_argument("--episodes", type=int, default=episodes)
    return ap.parse_args()


def played(args: argparse.Namespace, observer: Callable[[], object]) -> Iterator[tuple]:
    """Each chosen episode's record and its observer, as ``eval`` chooses and plays them."""
    cfg = RunConfig(args.policy, "I", "test", args.dataset, args.episodes,
                    env="HeteroTidy-v2", segmentation=args.segmentation)  # fmt: skip
    env, team = make_env(cfg), make_run_team(cfg)
    try:
        for i in select([e.start for e in env.unwrapped.episodes.episodes], args.episodes):
            log = observer()
            yield play_episode(env, team, i, i, [log]), log
    finally:
        env.close()
