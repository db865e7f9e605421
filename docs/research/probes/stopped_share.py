"""How many of a team's agent-steps are by agents that have stopped (issue 48).

    python docs/research/probes/stopped_share.py expert --episodes 4

Plays evenly spread Setting I test episodes and counts, at every step, the agents that have
taken ``Stop``: their cameras are off (``envs/hetero_tidy.py``), so this is the share of agent
cameras the env no longer draws for this team. Nothing is written.
"""

from __future__ import annotations

import argparse
from collections import Counter

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.policies import make_team


class StoppedCount:
    """An episode observer: steps by the number of agents stopped at them."""

    def __init__(self) -> None:
        self.steps: Counter = Counter()

    def start(self, env, team, channel) -> None:
        self.env = env

    def observed(self, t: int, obs: dict, info: dict) -> None:
        self.steps[sum(a.stopped for a in self.env.agents)] += 1


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy")
    p.add_argument("--episodes", type=int, default=4)
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()

    cfg = RunConfig(args.policy, "I", "test", args.dataset, args.episodes)
    env, team = make_env(cfg), make_team(args.policy)
    count = StoppedCount()
    try:
        chosen = select([e.start for e in env.unwrapped.episodes.episodes], args.episodes)
        for i in chosen:
            play_episode(env, team, i, i, [count])
        agents = len(env.unwrapped.agents)
    finally:
        env.close()
    total = sum(count.steps.values())
    stopped = sum(k * v for k, v in count.steps.items())
    print(f"{args.policy}: {len(chosen)} episodes, {total} steps; steps by agents stopped "
          f"{dict(sorted(count.steps.items()))}; {stopped / (agents * total):.0%} of "
          f"agent-steps by stopped agents")  # fmt: skip


if __name__ == "__main__":
    main()
