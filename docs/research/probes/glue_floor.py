"""What a learned team's step costs besides its models' arithmetic (issue 48).

    TIDY_AGENT_THREADS=1 python docs/research/probes/glue_floor.py [--policy hangrcom] \
        [--env HeteroTidy-v1]

Plays a Setting I test episode in blocks of team steps, in turns: as it is, and with the
models' forward passes free (the perception model, F_s, the communication generators, F_a and
F_g return their previous outputs for the same agent instead of computing). What the free
blocks still spend is everything else an agent does each step: reading its frame into the
map, the detections, HanGrCom's exchange, decoding the heads and the executor. That is the
floor no cheaper model can go below. The free blocks play other decisions (stale outputs), so
only their time is read; the env's own steps are timed beside them, since the ratio to the env
alone is the issue's measure. Nothing is written.
"""

from __future__ import annotations

import argparse
import os
import time

import torch

from maniskill_tidy.eval.episode import Execution
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.models.decision import AgentDecision, StateExtractor
from maniskill_tidy.models.hangrcom import HanGrCom
from maniskill_tidy.models.perception import PerceptionModel
from maniskill_tidy.policies import make_team


def free_forwards(free: dict) -> None:
    """Wrap the models' per-step calls: while ``free["on"]``, each returns what it returned
    last for the same module (the detections' per-row outputs sized to this frame's)."""
    last: dict = {}

    def step_features(self, rgb, seen, crop, det_row, *rest, _f=PerceptionModel.step_features):
        key = ("perception", id(self), len(rgb))
        if not free["on"] or key not in last:
            last[key] = _f(self, rgb, seen, crop, det_row, *rest)
            return last[key]
        out = dict(last[key])
        out["p_detections"] = torch.zeros(len(det_row))
        out["p_receptacles"] = torch.zeros(len(det_row), out["p_receptacles"].shape[-1])
        return out

    def cached(owner: type, name: str) -> None:
        method = getattr(owner, name)

        def call(self, *a, _m=method, _name=name, **k):
            key = (_name, id(self))
            if not free["on"] or key not in last:
                last[key] = _m(self, *a, **k)
            return last[key]

        setattr(owner, name, call)

    PerceptionModel.step_features = step_features
    cached(StateExtractor, "forward")  # F_s
    cached(AgentDecision, "decide")  # F_a and F_g
    cached(HanGrCom, "forward")  # HanGrCom's generators (other schemes' messengers compute)


def main() -> None:
    # the agents think in this process, where the measuring wrappers are
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="hangrcom")
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--blocks", type=int, default=8, help="blocks of 20 team steps, in turns")
    args = p.parse_args()
    free = {"on": False}
    free_forwards(free)
    env = make_env(RunConfig(args.policy, "I", "test", args.dataset, 1, env=args.env))
    team = make_team(args.policy)
    i = select([e.start for e in env.unwrapped.episodes.episodes], 1)[0]
    obs, info = env.reset(seed=i, options={"episode": i})
    execution = Execution(team, env.unwrapped, i)
    spent = {False: [], True: []}
    env_spent: list[float] = []
    for block in range(args.blocks + 1):  # the first block warms up and is not counted
        free["on"] = block % 2 == 0
        for _ in range(20):
            start = time.perf_counter()
            actions = execution.step(obs, info)
            if block:
                spent[free["on"]].append(time.perf_counter() - start)
            start = time.perf_counter()
            obs, _, terminated, truncated, info = env.step(actions)
            if block:
                env_spent.append(time.perf_counter() - start)
            if terminated or truncated:
                obs, info = env.reset(seed=i, options={"episode": i})
                execution = Execution(team, env.unwrapped, i)
    env.close()
    ms = {k: 1e3 * sum(v) / max(len(v), 1) for k, v in spent.items()}
    env_ms = 1e3 * sum(env_spent) / len(env_spent)
    print(f"{args.policy} on {args.env}, per team step ({args.blocks} blocks of 20 in turns): "
          f"as it is {ms[False]:.2f} ms, models free {ms[True]:.2f} ms; the env's step "
          f"{env_ms:.2f} ms, so team / env alone {1 + ms[False] / env_ms:.2f} as it is and "
          f"{1 + ms[True] / env_ms:.2f} with free models")  # fmt: skip


if __name__ == "__main__":
    main()
