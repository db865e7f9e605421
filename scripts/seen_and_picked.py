"""Per episode: how many misplaced objects any agent and the manipulators saw, and how many the
team picked up, for one or more teams on the same episodes. It tells a team that cannot find
the objects from one that finds them and does not fetch them (docs/research/research-log.md, "The
learned team: how we got there").

    .venv/bin/python scripts/seen_and_picked.py --episodes 0,50,100,150 \
        agents/experiments/hangrcom-3tasks.yaml heuristic-detection

An instrument, like the recorder: it reads the simulator, the teams do not.
"""

from __future__ import annotations

import argparse

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env
from maniskill_tidy.policies import make_team


class Seen:
    """Misplaced objects each agent had in view with at least MIN_PIXELS pixels."""

    def start(self, env, team, channel) -> None:
        self.env = env
        self.seen: dict[str, set] = {a.name: set() for a in env.agents}

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        u = self.env
        misplaced = {u.manipulation.seg_of_object[o]: o for o in u.misplaced}
        for a in u.agents:
            ids, counts = np.unique(np.asarray(obs[a.name]["segmentation"]), return_counts=True)
            for i, n in zip(ids, counts, strict=True):
                if int(i) in misplaced and n >= MIN_PIXELS:
                    self.seen[a.name].add(misplaced[int(i)])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("teams", nargs="+", help="policy names or agent configs")
    p.add_argument("--episodes", default="0,50,100,150", help="episode indices, comma-separated")
    p.add_argument("--split", default="val", choices=("train", "val", "test"))
    p.add_argument("--setting", default="I")
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()
    print("team | episode | misplaced | seen by anyone | seen by a manipulator | picked up")
    for policy in args.teams:
        env = make_env(RunConfig(policy, args.setting, args.split, args.dataset, "standard"), True)
        for i in map(int, args.episodes.split(",")):
            seen = Seen()
            r = play_episode(env, make_team(policy), i, i, [seen])
            manipulators = [a.name for a in env.unwrapped.agents if a.capability[1]]
            anyone = set().union(*seen.seen.values())
            by_manipulator = set().union(*(seen.seen[m] for m in manipulators))
            print(f"{policy} | {i} | {r.k} | {len(anyone)} | {len(by_manipulator)} | {r.found}")
        env.close()


if __name__ == "__main__":
    main()
