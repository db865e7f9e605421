"""Why a pixels team leaves detected objects where they are: for each misplaced object an agent's
mask of its type covered (``pixels-losses``: "detected"), how far the team's own memory took
it. Which agents showed it (and whether one could pick up), whether an agent's memory held it
and judged it misplaced, whether a manipulator took a job to fetch it, and how its PickUps
ended. Tells "the team never knew it was misplaced" from "it went for it and failed".

    .venv/bin/python docs/research/probes/pixels_unpicked.py --policy memory \\
        --dataset data/tidy120 --episodes 12 [--split val]
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
import pixels_probe

from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.eval.pixels_losses import PixelsLosses
from maniskill_tidy.perception.detections import detect_objects, resting_place, surfaces_under

NEAR = 0.5  # metres from an object: a teammate's report this close is of it


class Unpicked(PixelsLosses):
    """``pixels-losses``' observer, also following each object's slots into the agents'
    memories (``HeuristicAgent.objects``), jobs and PickUps."""

    def start(self, env, team, channel) -> None:
        super().start(env, team, channel)
        self.flags: dict[str, set[str]] = defaultdict(set)
        self.pickups: dict[str, Counter] = defaultdict(Counter)
        self.aimed: dict[str, str] = {}  # agent -> object its PickUp this step aimed at
        self.why_not_kept: dict[str, Counter] = defaultdict(Counter)

    def decided(self, t, actions, labels) -> None:
        super().decided(t, actions, labels)
        self.aimed = {}
        for oid in self.misplaced:
            for name, sid in self.slots[oid]:
                agent = self.agents[name]
                inner, slot_id = agent.inner, agent.table.instances[sid].id
                manip = "manipulator" if inner.manipulator else "other"
                self.flags[oid].add(f"shown to a {manip}")
                if agent.table.instances[sid].type == self.type_of[oid]:
                    self.flags[oid].add(f"shown to a {manip} as its type")
                known = inner.objects.get(slot_id)
                if known is not None:
                    self.flags[oid].add(f"in a {manip}'s memory")
                    if known.misplaced:
                        self.flags[oid].add(f"judged misplaced by a {manip}")
                elif (inner.manipulator and agent.table.instances[sid].type == self.type_of[oid]
                      and (agent.seg == sid).any()):  # fmt: skip
                    self.why_not_kept[oid].update(why_not_kept(inner, sid))
                job = inner.job
                if job is not None and job.kind == "pick" and job.target == slot_id:
                    self.flags[oid].add("a manipulator's pick job")
                a = actions.get(name)
                if isinstance(a, Targeted) and a.action == Action.PickUp and a.target != (-1, -1):
                    if agent.aimed == sid:
                        self.aimed[name] = oid

        for agent in self.agents.values():  # what teammates' messages told manipulators
            inner = agent.inner
            if not inner.manipulator:
                continue
            for oid in self.misplaced:
                xy = np.asarray(self.env.hs.object_bottom(oid))[:2]
                for r, how in [(r, "reported") for r in inner.reports] + [
                    (r, "report dismissed") for r in inner.dismissed
                ]:
                    if np.hypot(*(np.asarray(r.xy) - xy)) < NEAR:
                        same = "its type" if r.type == self.type_of[oid] else "another type"
                        self.flags[oid].add(f"{how} to a manipulator as {same}")

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        super().log_step(t, obs, actions, info, channel, labels)
        for name, oid in self.aimed.items():
            reason = info.get("failed", {}).get(name, "")
            self.pickups[oid][reason.split(":")[-1].strip()[:40] if reason else "picked"] += 1


def why_not_kept(inner, sid: int) -> list[str]:
    """Why a manipulator's memory did not take the slot its frame showed (``HeuristicAgent.
    observe``): too few points with a depth for ``detect_objects``, or resting on nothing the
    floor plan knows (``resting_place``: its lowest point, LOW-th percentile of its heights,
    further than ON_SURFACE from every surface under it and above ON_FLOOR), with the gap."""
    frame = inner.map.last_frame
    d = next((d for d in detect_objects(frame, inner.public.instances) if d.seg_id == sid), None)
    if d is None:
        return ["too few points"]
    if d.object_id in inner.done:
        return ["given up before (in the agent's done)"]
    receptacle, _, _ = resting_place(inner.house, d, inner.surfaces)
    if receptacle:
        return ["rests on a known surface (taken after the step, or forgotten)"]
    x, y = float(d.position[0]), float(d.position[1])
    under = [s.height for s in surfaces_under(x, y, inner.surfaces)]
    if not under:
        return [f"no surface under it, bottom {d.bottom:.2f} m"]
    gap = min(under, key=lambda h: abs(d.bottom - h)) - d.bottom
    return [f"bottom {'below' if gap > 0 else 'above'} the nearest surface by >= "
            f"{int(abs(gap) * 20) * 5} cm"]  # fmt: skip


STAGES = (
    "shown to a manipulator",
    "shown to a manipulator as its type",
    "in a manipulator's memory",
    "judged misplaced by a manipulator",
    "a manipulator's pick job",
)


def main() -> None:
    args = pixels_probe.arguments(__doc__, "memory", 12)
    reached: Counter = Counter()
    outcomes: Counter = Counter()
    fates: Counter = Counter()
    why: Counter = Counter()
    for record, log in pixels_probe.played(args, Unpicked):
        for o, oid in zip(log.result()["objects"], log.misplaced, strict=True):
            fates[o["fate"]] += 1
            if o["fate"] != "detected, not picked":
                continue
            last = next(
                (s for s in reversed(STAGES) if s in log.flags[oid]), "shown only to others"
            )
            reached[last] += 1
            outcomes.update(log.pickups[oid])
            print(f"{record.episode} {o['type']}: {sorted(log.flags[oid])} "
                  f"pickups {dict(log.pickups[oid])}")  # fmt: skip
            if last == "shown to a manipulator as its type":
                print(f"    not kept, frames by reason: {dict(log.why_not_kept[oid])}")
                why.update(log.why_not_kept[oid])
    print("fates:", dict(fates))
    print("detected, not picked: the furthest each got")
    for s in ("shown only to others", *STAGES):
        print(f"  {reached[s]:3d}  {s}")
    print("their PickUps:", dict(outcomes))
    print("frames where a manipulator was shown one as its type and its memory did not take it:",
          dict(why))  # fmt: skip


if __name__ == "__main__":
    main()
