"""How much of the env's own step is reading the cameras, and how many cores it keeps busy.

    python docs/research/probes/render_share.py [--env HeteroTidy-v1] [--policy heuristic-none]

Plays one Setting I test episode with ``--policy``, then replays its actions through the env
alone twice (as ``bench --only teams`` does) and prints, per replay, the wall and CPU seconds
of the whole replay and of the pictures' reading (``_read_pictures``) and taking: the CPU the
two cores have left beside the renderer bounds what a team can overlap with it (issue 48).
Nothing is written.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.eval.team_benchmark import ActionLog, replay
from maniskill_tidy.policies import make_team


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--policy", default="heuristic-none")
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()

    env = make_env(RunConfig(args.policy, "I", "test", args.dataset, 1, env=args.env))
    i = select([e.start for e in env.unwrapped.episodes.episodes], 1)[0]
    log = ActionLog()
    play_episode(env, make_team(args.policy), i, i, [log])
    u = env.unwrapped
    spent = {"read": [0.0, 0.0], "take": [0.0, 0.0]}

    def timed(name, method):
        def wrapper(*a, **k):
            wall, busy = time.perf_counter(), cpu()
            try:
                return method(*a, **k)
            finally:
                spent[name][0] += time.perf_counter() - wall
                spent[name][1] += cpu() - busy

        return wrapper

    u._read_pictures = timed("read", u._read_pictures)
    u._take_pictures = timed("take", u._take_pictures)
    for _ in range(2):
        for v in spent.values():
            v[:] = [0.0, 0.0]
        wall, busy = time.perf_counter(), cpu()
        replay(env, i, i, log.steps)
        wall, busy = time.perf_counter() - wall, cpu() - busy
        parts = ", ".join(f"{n} {w:.2f} s wall, {c:.2f} s CPU ({c / max(w, 1e-9):.2f} cores)"
                          for n, (w, c) in spent.items())  # fmt: skip
        print(f"{len(log.steps)} steps: {wall:.2f} s wall, {busy:.2f} s CPU "
              f"({busy / wall:.2f} cores); pictures: {parts}")  # fmt: skip
    env.close()


if __name__ == "__main__":
    main()
