"""How much of an evaluation is the team thinking: ``bench --only teams``.

Per team, on the same Setting I test episodes in one run: seconds per episode of the team
playing, and of the env alone, that is the team's own actions replayed through a fresh reset
with the same seed and the team's observation mode (the same renders, no perception, map,
decision or messages). The ratio is the team's cost in units of the env's. The replay must end
as the episode did (same success and objects placed), or the figure is refused.

Then the 2-worker / 1-worker ratio of ``eval`` for each team, over the whole command and in
steady state: what a second process buys, and the cores each run kept busy; beside them the
same ratio for two CPU-bound loops, the most a second process can buy on this machine.
"""

from __future__ import annotations

import json
import resource
import tempfile
import time
from pathlib import Path

from maniskill_tidy.eval import agent_processes
from maniskill_tidy.eval.episode import Execution, play_episode
from maniskill_tidy.eval.runner import (
    RunConfig,
    evaluate,
    make_env,
    make_run_team,
    run_dir,
    select,
)

TEAMS = ("heuristic-none", "heuristic-broadcast", "hangrcom", "memory")
PIXELS_TEAMS = ("heuristic-none", "memory")  # also timed in the pixels track, where weights are


class ActionLog:
    """The actions a team took, step by step (an episode observer)."""

    def start(self, env, team, channel) -> None:
        self.steps: list[dict] = []

    def decided(self, t, actions, labels) -> None:
        self.steps.append(dict(actions))


def replay(env, index: int, seed: int, steps: list[dict]) -> dict:
    """The env alone: reset as the episode was, then step the recorded actions."""
    env.reset(seed=seed, options={"episode": index})
    info: dict = {}
    for actions in steps:
        _, _, terminated, truncated, info = env.step(actions)
        if terminated or truncated:
            break
    return info


def bench_team(
    policy: str,
    episodes: int = 3,
    dataset: str | None = None,
    env_id: str = "HeteroTidy-v1",
    segmentation: str = "ground-truth",
) -> dict:
    """``segmentation``: "learned" times the team in the pixels track (its segmenter, instances
    and labels inside the team's time, each also per frame)."""
    cfg = RunConfig(policy, "I", "test", dataset, episodes, env=env_id, segmentation=segmentation)
    env, team = make_env(cfg), make_run_team(cfg)
    seconds = {"team": 0.0, "env": 0.0}
    try:
        chosen = select([e.start for e in env.unwrapped.episodes.episodes], episodes)
        # A team's first step in a process pays what a process pays once: a learned team
        # loads its models (seconds of imports) when its first agents are made, the map's
        # kernels load from numba's cache at their first call, torch sets up its kernels.
        # Take one step of throwaway agents before the clock starts, so the figure is per
        # episode: the agents of every timed episode are made afresh.
        obs, info = env.reset(seed=chosen[0], options={"episode": chosen[0]})
        Execution(team, env.unwrapped, chosen[0]).step(obs, info)
        segmenter = getattr(team, "segmenter", None)
        if segmenter is not None:  # count the timed episodes only
            segmenter.seconds = dict.fromkeys(segmenter.seconds, 0.0)
            segmenter.frames = 0
        for i in chosen:
            log = ActionLog()
            start = time.perf_counter()
            record = play_episode(env, team, i, i, [log])
            seconds["team"] += time.perf_counter() - start
            start = time.perf_counter()
            info = replay(env, i, i, log.steps)
            seconds["env"] += time.perf_counter() - start
            if (bool(info["success"]), int(info["n_reasonable"])) != (
                record.success, record.reasonable
            ):  # fmt: skip
                raise RuntimeError(f"{policy}: replaying {record.episode} ended otherwise")
    finally:
        env.close()
    n = len(chosen)
    row = {
        "team": policy
        + ("-pixels" if cfg.pixels else "")
        + ("" if segmentation in ("ground-truth", "learned") else f" ({segmentation})"),
        "env_id": env_id,
        "episodes": n,
        "team_s": seconds["team"] / n,
        "env_s": seconds["env"] / n,
        "ratio": seconds["team"] / seconds["env"],
    }
    if segmenter is not None and segmenter.frames:
        row["frames"] = segmenter.frames
        row["ms_per_frame"] = {k: 1000 * v / segmenter.frames for k, v in segmenter.seconds.items()}
    return row


def pixels_jobs(
    teams: list[str], looks: tuple[str, ...], segmentation: str = "learned"
) -> list[tuple[str, str, str]]:
    """(team, look, ``segmentation``) for each look whose segmenter is trained (``make
    train-segmenter``; or a segmenter's folder, to time another one); the others are left out,
    and said so."""
    import sys

    jobs = []
    for look in looks:
        cfg = RunConfig("heuristic-none", "I", "test", None, 1, env=look, segmentation=segmentation)
        weights = Path(cfg.segmenter()) / "model.pt"
        if not weights.is_file():
            print(f"pixels rows of {look} left out: no {weights} (make train-segmenter)",
                  file=sys.stderr)  # fmt: skip
            continue
        jobs += [(team, look, segmentation) for team in teams]
    return jobs


def cpu_seconds() -> float:
    """CPU time of this process, its finished child processes and its agents' live hosts
    (user + system)."""
    own, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    hosts = agent_processes.hosts_cpu_seconds()
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime + hosts


def bench_workers(policy: str, episodes: int = 6, dataset: str | None = None) -> dict:
    """``eval`` with 2 local processes over 1, on the same episodes: the ratio of episodes per
    hour over the whole command (``two_over_one``: start-up included, which a short run
    cannot amortise), in steady state (``steady``: from the episodes' own seconds, 2 x the
    1-worker sum over the 2-worker sum; slightly high where one worker's last episode runs
    alone), and the cores one process keeps busy (CPU seconds / wall seconds): lavapipe and
    the agents run on threads, so one process already uses more than one core and 2 / that
    is the most a second process can add on a 2-core machine."""
    cfg = RunConfig(policy, "I", "test", dataset, episodes)
    rate, busy, played = {}, {}, {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory(prefix="bench-teams-") as out:
            start, cpu = time.perf_counter(), cpu_seconds()
            summary = evaluate(cfg, Path(out), workers, progress=False)
            wall = time.perf_counter() - start
            rate[workers], busy[workers] = summary["episodes"] / wall, (cpu_seconds() - cpu) / wall
            lines = (run_dir(Path(out), cfg) / "episodes.jsonl").read_text().splitlines()
            played[workers] = sum(json.loads(line)["seconds"] for line in lines)
    return {"team": policy, "episodes": episodes, "two_over_one": rate[2] / rate[1],
            "steady": 2 * played[1] / played[2], "cores_one": busy[1],
            "cores_two": busy[2]}  # fmt: skip


# a fixed CPU-bound job in a bare interpreter (no threads, no imports); prints its seconds
SPIN = (
    "import time\nt = time.perf_counter()\nx = 0\n"
    "for i in range(12_000_000): x += i\nprint(time.perf_counter() - t)"
)


def bench_machine(rounds: int = 5) -> dict:
    """What a second process can add on this machine at best: two copies of a CPU-bound
    Python loop side by side against one alone, as work per second (the median of ``rounds``
    alternating rounds). On a 2-core virtual machine whose cores share a physical one, or
    a busy host, this is well below 2, and it bounds every 2-worker / 1-worker ratio."""
    import statistics
    import subprocess
    import sys

    def run(copies: int) -> list[float]:
        procs = [
            subprocess.Popen([sys.executable, "-c", SPIN], stdout=subprocess.PIPE, text=True)
            for _ in range(copies)
        ]
        return [float(proc.communicate()[0]) for proc in procs]

    ratios = []
    for _ in range(rounds):
        (alone,) = run(1)
        pair = run(2)
        ratios.append(sum(alone / t for t in pair))
    return {"rounds": rounds, "two_over_one": statistics.median(ratios),
            "spread": (min(ratios), max(ratios))}  # fmt: skip


def report(
    rows: list[dict], workers: list[dict], demos: list[dict] = (), machine: dict | None = None
) -> str:
    lines = [
        "teams: seconds per episode playing, and of the env alone replaying the same actions",
        f"{'team':>20} {'env':>13} {'episodes':>8} {'team s/ep':>9} {'env s/ep':>8} {'x env':>6}",
    ]
    for r in rows:
        lines.append(
            f"{r['team']:>20} {r['env_id']:>13} {r['episodes']:>8} {r['team_s']:>9.2f} "
            f"{r['env_s']:>8.2f} {r['ratio']:>6.2f}"
        )
    pixels = [r for r in rows if "ms_per_frame" in r]
    if pixels:
        lines.append(f"{'pixels track':>20} {'env':>13} {'frames':>8} ms per agent frame: "
                     "segmenter (ONNX Runtime, batched) / instances / labels, tracks")  # fmt: skip
    for r in pixels:
        ms = r["ms_per_frame"]
        lines.append(f"{r['team']:>20} {r['env_id']:>13} {r['frames']:>8} {'':>20}"
                     f"{ms['segmenter']:.1f} / {ms['instances']:.1f} / "
                     f"{ms['labels']:.1f}")  # fmt: skip
    # one process already keeping c cores busy, two on 2 cores can do at most 2 / c as much
    if workers:
        lines.append(f"{'team':>20} {'episodes':>8} {'2 workers / 1':>14} {'steady':>7} "
                     f"{'cores busy 1 / 2':>17} {'2 / cores 1':>11}")  # fmt: skip
    for w in workers:
        lines.append(
            f"{w['team']:>20} {w['episodes']:>8} {w['two_over_one']:>14.2f} "
            f"{w['steady']:>7.2f} {w['cores_one']:>8.2f} {w['cores_two']:>8.2f} "
            f"{2 / w['cores_one']:>11.2f}"
        )
    if machine:
        low, high = machine["spread"]
        lines.append(f"{'this machine':>20} {'':>8} {machine['two_over_one']:>14.2f} "
                     f"(two CPU-bound Python loops over one; {low:.2f}-{high:.2f} in "
                     f"{machine['rounds']} rounds)")  # fmt: skip
    if demos:
        lines.append(f"{'demos --features':>20} {'env':>13} {'traj.':>8} {'s/traj.':>9} "
                     f"{'steady':>7} {'demos hash':>12}")  # fmt: skip
        for d in demos:
            lines.append(f"{'':>20} {d['env_id']:>13} {d['trajectories']:>8} "
                         f"{d['seconds']:>9.2f} {d['steady_s']:>7.2f} "
                         f"{d['demos_hash'][:12]:>12}")  # fmt: skip
    return "\n".join(lines)
