"""Wall time of chosen methods over one Setting I test episode, unprofiled (issue 48).

    TIDY_AGENT_THREADS=1 python docs/research/probes/team_split.py hangrcom \
        maniskill_tidy.policies.executor.SubGoalExecutor.move \
        maniskill_tidy.models.perception.PerceptionModel.step_features

Each ``module.Class.method`` is wrapped with a timer; the team plays two episodes and the second
is reported (the first loads models and compiles kernels), with the cores the team's steps
keep busy (process CPU seconds over wall seconds of ``Execution.step``: above 1 where the
agents' threads, ``TIDY_AGENT_THREADS``, think side by side). cProfile (``profile_team.py``)
says where time goes; this says how long a call takes without its overhead. Nothing is written.
"""

from __future__ import annotations

import argparse
import importlib
import os
import time
from collections import Counter

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.policies import make_team


def main() -> None:
    # the agents think in this process, where the measuring wrappers are
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy")
    p.add_argument("methods", nargs="+", help="module.Class.method to time")
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()

    spent, calls, cpu = Counter(), Counter(), Counter()
    for path in [*args.methods, "maniskill_tidy.eval.episode.Execution.step"]:
        module, cls, name = path.rsplit(".", 2)
        owner = getattr(importlib.import_module(module), cls)
        method = getattr(owner, name)

        def timed(*a, _method=method, _path=path, **k):
            start, start_cpu = time.perf_counter(), time.process_time()
            try:
                return _method(*a, **k)
            finally:
                spent[_path] += time.perf_counter() - start
                cpu[_path] += time.process_time() - start_cpu
                calls[_path] += 1

        setattr(owner, name, timed)

    cfg = RunConfig(args.policy, "I", "test", args.dataset, 2, env=args.env)
    env, team = make_env(cfg), make_team(args.policy)
    first, second = select([e.start for e in env.unwrapped.episodes.episodes], 2)
    play_episode(env, team, first, first)
    spent.clear()
    calls.clear()
    cpu.clear()
    start = time.perf_counter()
    play_episode(env, team, second, second)
    step = "maniskill_tidy.eval.episode.Execution.step"
    print(f"{args.policy} on {args.env}: episode {time.perf_counter() - start:.2f} s; the "
          f"team's steps keep {cpu[step] / spent[step]:.2f} cores busy")  # fmt: skip
    for path, seconds in spent.most_common():
        n = calls[path]
        print(f"{seconds:8.3f} s {n:6d} calls {1e3 * seconds / n:8.3f} ms/call  {path}")
    env.close()


if __name__ == "__main__":
    main()
