"""What became of each misplaced object in a team's episodes (the ground-truth track): never in
view, seen but never picked up, picked up but not put where it belongs, or tidied.

``maniskill-tidy object-fates memory --setting I --split val --episodes 40`` plays the episodes
(evenly spread, as ``eval --episodes N``; seed ``i`` for episode ``i``) with an observer that has
the benchmark's full access (an instrument, not part of the team): a misplaced object counts as
*in view* from the first step at which it covers at least ``MIN_PIXELS`` pixels of some agent's
segmentation (the detector's stand-in, the threshold the agents' own perception uses), whether
or not the team then recognised it as misplaced. Objects in view and never picked are split by
whether a manipulator (who could pick them up) ever had them in view, and by what the agents'
own detections judged them (agents of the heuristic's kind, ``heuristic-*`` and ``memory``;
misplaced if any agent ever judged so). Camera teams only: the expert reads the env, not its
cameras. A pixels run's records hold its own fates (``pixels-losses``).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS, NO_ROOM
from maniskill_tidy.envs.registration import ENV_ID

FATES = ("never in view", "in view, never picked", "picked, not placed", "placed")
REASONS = ("only non-manipulators had it in view", "a manipulator had it in view")
BELIEFS = ("no agent's own detection", "judged in place", "judged misplaced")


class ObjectFates:
    """The observer (``eval/episode.py``): each misplaced object's first step in view, first
    step held, and whether it ends where it belongs."""

    def __init__(self, trace: bool = False) -> None:
        self.agents: list = []  # the team's agents (``executing``)
        self.tracing, self.trace = trace, []  # every operation and its outcome, with --trace

    def executing(self, agents: dict) -> None:  # the instrument watches their beliefs
        self.agents = list(agents.values())

    def start(self, env, team, channel) -> None:
        self.env = env
        self.misplaced = list(env.misplaced)
        self.seg = {seg: inst.id for seg, inst in env.instances.items() if inst.kind == "object"}
        self.manipulators = {a.name for a in env.agents if a.capability[1]}
        self.seen: dict[str, int] = {}
        self.seen_by_manipulator: dict[str, int] = {}
        self.picked: dict[str, int] = {}
        self.judged: dict[str, set[bool]] = {}
        self.failures: Counter = Counter()  # failed actions by kind, and steps spent carrying
        self.known_to_manipulator: set[str] = set()  # a manipulator's own detection: misplaced
        self.given_up: set[str] = set()  # a manipulator found no viewpoint to pick it up from

    def observed(self, t: int, obs: dict, info: dict) -> None:
        for name, agent_obs in obs.items():
            if "segmentation" not in agent_obs:
                raise ValueError("object-fates: the team's observation has no segmentation")
            ids, counts = np.unique(np.asarray(agent_obs["segmentation"]), return_counts=True)
            for seg, n in zip(ids.tolist(), counts.tolist(), strict=True):
                oid = self.seg.get(seg)
                if oid in self.misplaced and n >= MIN_PIXELS:
                    self.seen.setdefault(oid, t)
                    if name in self.manipulators:
                        self.seen_by_manipulator.setdefault(oid, t)
        for agent in self.agents:  # what the agents' own detections made of it (heuristic kin)
            manipulator = agent.name in self.manipulators
            for oid, known in getattr(agent, "objects", {}).items():
                if oid in self.misplaced:
                    self.judged.setdefault(oid, set()).add(bool(known.misplaced))
                    if manipulator and known.misplaced:
                        self.known_to_manipulator.add(oid)
            if manipulator:  # ``done``: tidied or given up; for one never picked, given up
                self.given_up |= set(getattr(agent, "done", ())) - set(self.picked)

    def log_step(self, t: int, obs, actions, info: dict, channel, labels) -> None:
        for oid in info.get("picked", []):
            self.picked.setdefault(oid, t)
        for reason in info.get("failed", {}).values():
            if reason:  # the PutDowns refused because the surface had no room for the object
                self.failures["no room" if reason.startswith(NO_ROOM) else "other"] += 1
        if self.tracing:  # every PickUp and PutDown, and how it ended
            for name, action in actions.items():
                if hasattr(action, "target"):
                    why = info.get("failed", {}).get(name) or "done"
                    self.trace.append(f"{t:>4} {name} {action.action.name} {action.target}: {why}")
        self.failures["steps carrying"] += sum(h is not None for h in info["held"].values())
        self.reasonable = set(info.get("reasonable", []))

    def rows(self, episode: str) -> list[dict]:
        task = self.env.episode.task
        out = []
        for m in task.misplaced:
            oid = m.object
            fate = (FATES[3] if oid in self.reasonable else FATES[2] if oid in self.picked
                    else FATES[1] if oid in self.seen else FATES[0])  # fmt: skip
            surface = m.misplaced.surface or ""
            where = ("floor" if m.misplaced.receptacle == "Floor" else "inside"
                     if surface.startswith(("in", "shelf", "cabinet")) else "on top")  # fmt: skip
            out.append({"episode": episode, "object": oid, "type": m.type, "where": where,
                        "height": round(float(m.misplaced.position[2]), 3),
                        "cross_room": m.original.room != m.misplaced.room, "fate": fate,
                        "seen": self.seen.get(oid), "picked": self.picked.get(oid),
                        "seen_by_manipulator": self.seen_by_manipulator.get(oid),
                        "judged": BELIEFS[max(self.judged.get(oid, {-1})) + 1],
                        "known_to_manipulator": oid in self.known_to_manipulator,
                        "given_up": oid in self.given_up})  # fmt: skip
        return out


_worker: dict = {}


def _init(cfg) -> None:
    from maniskill_tidy.eval.runner import make_env
    from maniskill_tidy.policies import make_team

    _worker.update(cfg=cfg, env=make_env(cfg), team=make_team(cfg.policy))
    return lambda: _worker["env"].close()


def _play(job: tuple[int, bool]) -> tuple[list[dict], Counter, list[str]]:
    from maniskill_tidy.eval.episode import play_episode

    index, trace = job
    fates = ObjectFates(trace=trace)
    seed = _worker["cfg"].seed + index
    record = play_episode(_worker["env"], _worker["team"], index, seed, [fates])
    return fates.rows(record.episode), fates.failures, fates.trace


def object_fates(policy: str, setting: str, split: str, episodes: int, dataset: str,
                 workers: int, trace: str | None = None, env: str = ENV_ID):  # fmt: skip
    """Play the episodes in look ``env``; returns (rows, failures, traces, number of
    episodes)."""
    from tqdm import tqdm

    from maniskill_tidy.common.parallel import run_jobs
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.eval.runner import RunConfig, select
    from maniskill_tidy.policies import POLICIES

    if policy not in POLICIES or policy == "expert":
        raise ValueError(f"policy {policy!r}: expected a camera team, one of "
                         f"{sorted(set(POLICIES) - {'expert'})}")  # fmt: skip
    if episodes <= 0:
        raise ValueError(f"--episodes {episodes}: expected a positive number")
    if dataset is not None and not Path(dataset).is_dir():
        raise ValueError(f"--dataset {dataset}: not found; expected a folder made by "
                         "`maniskill-tidy generate`")  # fmt: skip
    cfg = RunConfig(policy, setting, split, dataset, env=env)
    starts = EpisodeSet.for_setting(dataset, split, setting).episodes
    chosen = select([e.start for e in starts], episodes)
    if trace is not None:
        ids = [e.id for e in starts]
        if trace not in ids:
            raise ValueError(f"--trace {trace!r}: not an episode of {split}, Setting {setting}; "
                             f"expected an id such as {ids[0]!r}")  # fmt: skip
        chosen = [ids.index(trace)]
    rows: list[dict] = []
    failures: Counter = Counter()
    traces: list[str] = []
    with tqdm(total=len(chosen), desc=policy, unit="episode") as bar:
        jobs = [(i, trace is not None) for i in chosen]
        for _, (played, failed, lines) in run_jobs(jobs, _play, workers, init=_init,
                                                   initargs=(cfg,), ordered=True):  # fmt: skip
            rows.extend(played)
            failures += failed
            traces += lines
            bar.update(1)
    return rows, failures, traces, len(chosen)


def report(policy: str, setting: str, split: str, rows: list[dict], failures: Counter,
           episodes: int) -> str:  # fmt: skip
    """The fates per place an object was misplaced to, and why objects in view were missed."""
    lines = [f"{policy}, Setting {setting}, {split}: {episodes} episodes, "
             f"{len(rows)} misplaced objects",
             f"{'misplaced to':>14} {'n':>5} " + " ".join(f"{f:>22}" for f in FATES)]  # fmt: skip
    for where in ("floor", "on top", "inside", "all"):
        mine = [r for r in rows if where in ("all", r["where"])]
        n = Counter(r["fate"] for r in mine)
        lines.append(f"{where:>14} {len(mine):>5} " + " ".join(
            f"{n[f]:>10} ({n[f] / max(len(mine), 1):5.1%})    " for f in FATES))  # fmt: skip
    lines.append(f"failed actions: {failures['no room'] + failures['other']}, of them PutDown "
                 f"with no room on the surface: {failures['no room']}; agent-steps spent "
                 f"carrying an object: {failures['steps carrying']} of {episodes} "
                 "episodes")  # fmt: skip
    missed = [r for r in rows if r["fate"] == FATES[1]]
    if missed:
        lines.append(f"in view, never picked ({len(missed)}): first in view at step "
                     f"{np.median([r['seen'] for r in missed]):.0f} (median); "
                     f"{np.mean([r['cross_room'] for r in missed]):.0%} misplaced to another "
                     "room")  # fmt: skip
        n = Counter(REASONS[r["seen_by_manipulator"] is not None] for r in missed)
        lines.append("  " + "; ".join(f"{reason}: {n[reason]}" for reason in REASONS))
        n = Counter(r["judged"] for r in missed)
        lines.append("  " + "; ".join(f"{belief}: {n[belief]}" for belief in BELIEFS))
        known = [r for r in missed if r["known_to_manipulator"]]
        lines.append(f"  a manipulator's own detection judged it misplaced: {len(known)}, of "
                     "which a manipulator gave up on it (no viewpoint to pick it from): "
                     f"{sum(r['given_up'] for r in known)}")  # fmt: skip
    return "\n".join(lines)
