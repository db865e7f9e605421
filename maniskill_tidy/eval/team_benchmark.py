"""How much of an evaluation is the team thinking: ``bench --only teams``.

Per team, on the same Setting I test episodes in one run: seconds per episode of the team
playing, and of the env alone, that is the team's own actions replayed through a fresh reset
with the same seed and the team's observation mode (the same renders, no perception, map,
decision or messages). The ratio is the team's cost in units of the env's. The replay must end
as the episode did (same success and objects placed), or the figure is refused.

Then the 2-worker / 1-worker ratio of ``eval`` for each team: what a second process buys.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from maniskill_tidy.eval.episode import Execution, play_episode
from maniskill_tidy.eval.runner import RunConfig, evaluate, make_env, select
from maniskill_tidy.policies import make_team

TEAMS = ("heuristic-none", "heuristic-broadcast", "hangrcom")


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


def bench_team(policy: str, episodes: int = 3, dataset: str | None = None,
               env_id: str = "HeteroTidy-v1") -> dict:  # fmt: skip
    cfg = RunConfig(policy, "I", "test", dataset, episodes, env=env_id)
    env, team = make_env(cfg), make_team(policy)
    seconds = {"team": 0.0, "env": 0.0}
    try:
        chosen = select([e.start for e in env.unwrapped.episodes.episodes], episodes)
        # a learned team loads its models (seconds of imports) when its first agents are
        # made: do that before the clock starts, so the figure is per episode
        env.reset(seed=chosen[0], options={"episode": chosen[0]})
        Execution(team, env.unwrapped, chosen[0])
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
    return {
        "team": policy,
        "env_id": env_id,
        "episodes": n,
        "team_s": seconds["team"] / n,
        "env_s": seconds["env"] / n,
        "ratio": seconds["team"] / seconds["env"],
    }


def bench_workers(policy: str, episodes: int = 4, dataset: str | None = None) -> dict:
    """Episodes per hour of ``eval`` with 2 local processes over 1, on the same episodes."""
    cfg = RunConfig(policy, "I", "test", dataset, episodes)
    rate = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory(prefix="bench-teams-") as out:
            start = time.perf_counter()
            summary = evaluate(cfg, Path(out), workers, progress=False)
            rate[workers] = summary["episodes"] / (time.perf_counter() - start)
    return {"team": policy, "episodes": episodes, "two_over_one": rate[2] / rate[1]}


def report(rows: list[dict], workers: list[dict], demos: list[dict] = ()) -> str:
    lines = [
        "teams: seconds per episode playing, and of the env alone replaying the same actions",
        f"{'team':>20} {'env':>13} {'episodes':>8} {'team s/ep':>9} {'env s/ep':>8} {'x env':>6}",
    ]
    for r in rows:
        lines.append(
            f"{r['team']:>20} {r['env_id']:>13} {r['episodes']:>8} {r['team_s']:>9.2f} "
            f"{r['env_s']:>8.2f} {r['ratio']:>6.2f}"
        )
    lines.append(f"{'team':>20} {'episodes':>8} {'2 workers / 1':>14}")
    for w in workers:
        lines.append(f"{w['team']:>20} {w['episodes']:>8} {w['two_over_one']:>14.2f}")
    if demos:
        lines.append(f"{'demos --features':>20} {'env':>13} {'traj.':>8} {'s/traj.':>9} "
                     f"{'demos hash':>12}")  # fmt: skip
        for d in demos:
            lines.append(f"{'':>20} {d['env_id']:>13} {d['trajectories']:>8} "
                         f"{d['seconds']:>9.2f} {d['demos_hash'][:12]:>12}")  # fmt: skip
    return "\n".join(lines)
