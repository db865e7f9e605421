"""Where a team's episode goes: cProfile of a few Setting I test episodes (issue 48).

    python docs/research/probes/profile_team.py hangrcom --episodes 2 [--env HeteroTidy-v2] \
        [--top 40] [--callers REGEX]

Prints the functions with the most time of their own and the most cumulative time, and the
split between the env (reset, step) and the team (observe, send, act); ``--callers`` adds who
called the functions whose names match (``_unique_hash|astype``). Nothing is written.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import time

from maniskill_tidy.eval.episode import Execution, play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.policies import make_team


def main() -> None:
    # the agents think in this process, where the measuring wrappers are
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy")
    p.add_argument("--episodes", type=int, default=2)
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--top", type=int, default=40)
    p.add_argument("--callers", help="regex of functions whose callers to print")
    args = p.parse_args()

    cfg = RunConfig(args.policy, "I", "test", args.dataset, args.episodes, env=args.env)
    env, team = make_env(cfg), make_team(args.policy)
    chosen = select([e.start for e in env.unwrapped.episodes.episodes], args.episodes)
    spent = {"team": 0.0}
    step = Execution.step

    def timed_step(self, obs, info):  # the team's share: everything Execution.step does
        start = time.perf_counter()
        try:
            return step(self, obs, info)
        finally:
            spent["team"] += time.perf_counter() - start

    Execution.step = timed_step
    profile = cProfile.Profile()
    start = time.perf_counter()
    profile.enable()
    for i in chosen:
        play_episode(env, team, i, i)
    profile.disable()
    total = time.perf_counter() - start
    env.close()
    print(f"{args.policy} on {args.env}: {len(chosen)} episodes, {total:.1f} s "
          f"(profiled), team {spent['team']:.1f} s = {spent['team'] / total:.0%}")  # fmt: skip
    stats = pstats.Stats(profile)
    stats.sort_stats("tottime").print_stats(args.top)
    stats.sort_stats("cumulative").print_stats(args.top)
    if args.callers:
        stats.print_callers(args.callers)


if __name__ == "__main__":
    main()
