"""Agents on threads against agents in processes of their own, on the same episode (issue 48).

    python docs/research/probes/agent_processes_ab.py [--policy hangrcom] \
        [--env HeteroTidy-v1] [--rounds 3] [--phases]

Plays one Setting I test episode ``--rounds`` times each way, in turns (threads, processes,
threads, ...), after one throwaway episode each way (models load, hosts start): per team step,
the milliseconds of the team's step (``Execution.step``: observe, the rounds, act) and of the
env's, and the cores the team's steps kept busy (this process's CPU and the hosts' over wall
time). The records must be equal, or it stops. ``--phases`` adds, per phase of a step
(observe, send: one per communication round, act), its wall milliseconds and the CPU
milliseconds spent in it (this process's and the hosts'): where a phase's wall exceeds its CPU
over the cores, the agents wait on each other or on the messages. Nothing is written.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time

from maniskill_tidy.eval import agent_processes
from maniskill_tidy.eval.episode import Execution, play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.policies import make_team

MODES = {"threads": "0", "processes": "1"}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="hangrcom")
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--phases", action="store_true", help="time each phase of a team step")
    args = p.parse_args()

    clock = {"team": 0.0, "team_cpu": 0.0, "env": 0.0, "steps": 0}
    team_step, env_step = Execution.step, None

    def timed_team(self, obs, info):
        start, cpu = time.perf_counter(), time.process_time()
        hosts = agent_processes.hosts_cpu_seconds()
        try:
            return team_step(self, obs, info)
        finally:
            clock["team"] += time.perf_counter() - start
            clock["team_cpu"] += time.process_time() - cpu
            clock["team_cpu"] += agent_processes.hosts_cpu_seconds() - hosts
            clock["steps"] += 1

    Execution.step = timed_team
    phases: dict[str, list] = {}  # phase -> [calls, wall s, CPU s]
    each = Execution._each

    def hosts_cpu(execution) -> float:  # idle hosts are not read on threads (/proc costs)
        return agent_processes.hosts_cpu_seconds() if execution.remote else 0.0

    def timed_each(self, method, *a, **k):
        start, cpu, hosts = time.perf_counter(), time.process_time(), hosts_cpu(self)
        try:
            return each(self, method, *a, **k)
        finally:
            row = phases.setdefault(method, [0, 0.0, 0.0])
            row[0] += 1
            row[1] += time.perf_counter() - start
            row[2] += time.process_time() - cpu + hosts_cpu(self) - hosts

    if args.phases:
        Execution._each = timed_each
    phase_rows: dict[str, list[dict]] = {m: [] for m in MODES}
    cfg = RunConfig(args.policy, "I", "test", args.dataset, 1, env=args.env)
    env, team = make_env(cfg), make_team(args.policy)
    u = env.unwrapped
    env_step = type(u).step

    def timed_env(self, *a, **k):
        start = time.perf_counter()
        try:
            return env_step(self, *a, **k)
        finally:
            clock["env"] += time.perf_counter() - start

    type(u).step = timed_env
    (i,) = select([e.start for e in u.episodes.episodes], 1)
    results: dict[str, list] = {m: [] for m in MODES}
    records = {}
    for r in range(args.rounds + 1):
        for mode, knob in MODES.items():
            os.environ["TIDY_AGENT_PROCESSES"] = knob
            for k in clock:
                clock[k] = 0
            phases.clear()
            record = dataclasses.replace(play_episode(env, team, i, i), seconds=0.0)
            if records.setdefault(mode, record) != record or record != records["threads"]:
                raise SystemExit(f"{mode}: the record differs: {record} against {records}")
            if r == 0:
                continue  # throwaway: loads, starts
            n = clock["steps"]
            results[mode].append(
                (1e3 * clock["team"] / n, 1e3 * clock["env"] / n, clock["team_cpu"] / clock["team"])
            )
            phase_rows[mode].append(
                {m: (c / n, 1e3 * w / c, 1e3 * cpu / c) for m, (c, w, cpu) in phases.items()}
            )
            team_ms, env_ms, cores = results[mode][-1]
            print(f"round {r} {mode:9s}: team {team_ms:6.2f} ms/step, env {env_ms:6.2f} "
                  f"ms/step, team's steps keep {cores:.2f} cores busy", flush=True)  # fmt: skip
    env.close()
    print(f"{args.policy} on {args.env}, medians over {args.rounds} rounds (ms per team step):")
    for mode, rows in results.items():
        team_ms, env_ms, cores = (statistics.median(col) for col in zip(*rows, strict=True))
        print(f"  {mode:9s} team {team_ms:6.2f}  env {env_ms:6.2f}  (team + env) / env "
              f"{(team_ms + env_ms) / env_ms:.2f}  cores {cores:.2f}")  # fmt: skip
    if args.phases:
        print("per phase, medians over the rounds: calls per team step, wall and CPU ms per call")
        for mode, rows in phase_rows.items():
            for m in rows[0]:
                calls, wall, cpu = (statistics.median(r[m][j] for r in rows) for j in range(3))
                print(f"  {mode:9s} {m:8s} x{calls:.1f}  wall {wall:6.2f}  CPU {cpu:6.2f}")


if __name__ == "__main__":
    main()
