"""What became of each misplaced object in a team's episodes: never in view, seen but never
picked up, picked up but not put where it belongs, or tidied.

    python scripts/object_fates.py memory --setting I --split val --episodes 40

Plays ``--episodes`` episodes (evenly spread, as ``eval --episodes N``; seed ``i`` for episode
``i``) of the team with an observer that has the benchmark's full access (it is an instrument,
not part of the team): a misplaced object counts as *in view* from the first step at which it
covers at least ``MIN_PIXELS`` pixels of some agent's segmentation (the detector's stand-in,
the threshold the agents' own perception uses), whether or not the team then recognised it as
misplaced. Objects in view and never picked are split by whether a manipulator (who could pick
them up) ever had them in view, and by what the agents' own detections judged them (agents of
the heuristic's kind, ``heuristic-*`` and ``memory``; misplaced if any agent ever judged so).

Prints, per place the object was misplaced to (floor, on top, inside a shelf or compartment),
how many ended in each fate; writes one JSON line per object to ``--out``. Camera teams only:
the expert reads the env, not its cameras.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS, NO_ROOM

FATES = ("never in view", "in view, never picked", "picked, not placed", "placed")
REASONS = ("only non-manipulators had it in view", "a manipulator had it in view")
BELIEFS = ("no agent's own detection", "judged in place", "judged misplaced")


class ObjectFates:
    """The observer (``eval/episode.py``): each misplaced object's first step in view, first
    step held, and whether it ends where it belongs."""

    def __init__(self, agents: list | None = None, trace: bool = False) -> None:
        self.agents = agents if agents is not None else []  # the team's, filled as it makes them
        self.tracing, self.trace = trace, []  # every operation and its outcome, with --trace

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
                raise SystemExit("object_fates: the team's observation has no segmentation")
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
    team, made = _worker["team"], []
    make_agent = type(team).make_agent

    def keep(self, *args, **kwargs):  # the instrument watches the agents' beliefs
        made.append(make_agent(self, *args, **kwargs))
        return made[-1]

    team.make_agent = keep.__get__(team)
    try:
        fates = ObjectFates(made, trace)
        seed = _worker["cfg"].seed + index
        record = play_episode(_worker["env"], team, index, seed, [fates])
    finally:
        del team.make_agent
    return fates.rows(record.episode), fates.failures, fates.trace


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy", help="a camera team (memory, heuristic-detection, hangrcom, ...)")
    p.add_argument("--setting", default="I", choices=["I", "II"])
    p.add_argument("--split", default="val", choices=["train", "val", "test"])
    p.add_argument("--episodes", type=int, default=40)
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", type=Path, help="one JSON line per object (default: print only)")
    p.add_argument("--trace", metavar="EPISODE", help="play only this episode (an id: "
                   "house_00091/task_5/start_0) and print its PickUps and PutDowns")  # fmt: skip
    args = p.parse_args()
    from tqdm import tqdm

    from maniskill_tidy.common.parallel import run_jobs
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.eval.runner import RunConfig, select
    from maniskill_tidy.policies import POLICIES

    if args.policy not in POLICIES or args.policy == "expert":
        p.error(f"policy {args.policy!r}: expected a camera team, one of "
                f"{sorted(set(POLICIES) - {'expert'})}")  # fmt: skip
    if args.episodes <= 0:
        p.error(f"--episodes {args.episodes}: expected a positive number")
    if not Path(args.dataset).is_dir():
        p.error(f"--dataset {args.dataset}: not found; expected a folder made by "
                "`maniskill-tidy generate`")  # fmt: skip
    cfg = RunConfig(args.policy, args.setting, args.split, args.dataset)
    starts = EpisodeSet.for_setting(args.dataset, args.split, args.setting).episodes
    chosen = select([e.start for e in starts], args.episodes)
    if args.trace is not None:
        ids = [e.id for e in starts]
        if args.trace not in ids:
            p.error(f"--trace {args.trace!r}: not an episode of {args.split}, Setting "
                    f"{args.setting}; expected an id such as {ids[0]!r}")  # fmt: skip
        chosen = [ids.index(args.trace)]
    rows: list[dict] = []
    failures: Counter = Counter()
    traces: list[str] = []
    with tqdm(total=len(chosen), desc=args.policy, unit="episode") as bar:
        jobs = [(i, args.trace is not None) for i in chosen]
        for _, (played, failed, trace) in run_jobs(jobs, _play, args.workers, init=_init,
                                                   initargs=(cfg,), ordered=True):  # fmt: skip
            rows.extend(played)
            failures += failed
            traces += trace
            bar.update(1)
    for line in traces:
        print(line)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.out.with_suffix(".tmp")
        tmp.write_text("".join(json.dumps(r) + "\n" for r in rows))
        tmp.replace(args.out)
    print(f"{args.policy}, Setting {args.setting}, {args.split}: {len(chosen)} episodes, "
          f"{len(rows)} misplaced objects")  # fmt: skip
    print(f"{'misplaced to':>14} {'n':>5} " + " ".join(f"{f:>22}" for f in FATES))
    for where in ("floor", "on top", "inside", "all"):
        mine = [r for r in rows if where in ("all", r["where"])]
        n = Counter(r["fate"] for r in mine)
        print(f"{where:>14} {len(mine):>5} " + " ".join(
            f"{n[f]:>10} ({n[f] / max(len(mine), 1):5.1%})    " for f in FATES))  # fmt: skip
    print(f"failed actions: {failures['no room'] + failures['other']}, of them PutDown with no "
          f"room on the surface: {failures['no room']}; agent-steps spent carrying an object: "
          f"{failures['steps carrying']} of {len(chosen)} episodes")  # fmt: skip
    missed = [r for r in rows if r["fate"] == FATES[1]]
    if missed:
        print(
            f"in view, never picked ({len(missed)}): first in view at step "
            f"{np.median([r['seen'] for r in missed]):.0f} (median); "
            f"{np.mean([r['cross_room'] for r in missed]):.0%} misplaced to another room"
        )
        n = Counter(REASONS[r["seen_by_manipulator"] is not None] for r in missed)
        print("  " + "; ".join(f"{reason}: {n[reason]}" for reason in REASONS))
        n = Counter(r["judged"] for r in missed)
        print("  " + "; ".join(f"{belief}: {n[belief]}" for belief in BELIEFS))
        known = [r for r in missed if r["known_to_manipulator"]]
        print(f"  a manipulator's own detection judged it misplaced: {len(known)}, of which "
              f"a manipulator gave up on it (no viewpoint to pick it from): "
              f"{sum(r['given_up'] for r in known)}")  # fmt: skip


if __name__ == "__main__":
    main()
