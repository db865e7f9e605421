"""What a pixels team's PickUp and PutDown actions met: per episode and in all, how many it
issued and why each failed (the env's reasons, grouped; a PickUp of an object not in the frame
also by whether the renderer showed one of the aimed type), and how many of the object slots
agents showed their team were ever an object of their type. Tells "detected, not picked"
(``pixels-losses``) apart: tried at a pixel with nothing drawn, out of reach, or chasing a
detection that is not there. A PickUp aimed at no pixel (its target out of the frame) is also
counted by the track behind the object it named: one the agent had already refuted (its team
still fetching what its perception took back), one still live, or none.

    .venv/bin/python docs/research/probes/pixels_actions.py --policy heuristic-none \\
        --dataset data/tidy120 --episodes 4
"""

from __future__ import annotations

import re
from collections import Counter

import numpy as np
import pixels_probe

from maniskill_tidy.envs.actions import MIN_PIXELS, Action, Targeted


def kind(reason: str) -> str:
    """A failure reason without its ids, pixels and distances."""
    return re.sub(r"\(.*?\)|[A-Za-z]+_\d+\S*|\d+(\.\d+)?", "#", reason)[:70]


class ActionOutcomes:
    """An episode observer: each PickUp and PutDown with the env's answer; a PickUp failed
    for want of its target in view, also whether the renderer shows an object of the aimed
    type in the frame after it (the segmenter missed it) or none (a false detection)."""

    def start(self, env, team, channel) -> None:
        self.env, self.pending, self.counts = env, {}, Counter()
        self.agents: dict = {}

    def executing(self, agents) -> None:
        self.agents = agents
        self.slots: dict[tuple, bool] = {}  # (agent, slot) shown to the team -> ever real

    def observed(self, t, obs, info) -> None:
        self.truth = {n: np.asarray(o["segmentation"]) for n, o in obs.items()}

    def _judge_slots(self) -> None:
        """Each object slot an agent shows: real if most of its pixels, in some frame, are an
        object of its type."""
        for name, agent in self.agents.items():
            seg = getattr(agent, "seg", None)
            if seg is None or name not in self.truth:
                continue
            truth = self.truth[name].reshape(seg.shape)
            for sid in np.unique(seg[seg >= 1024]):
                under, n = np.unique(truth[seg == sid], return_counts=True)
                inst = self.env.instances.get(int(under[np.argmax(n)]))
                real = inst is not None and inst.type == agent.table.instances[int(sid)].type
                key = (name, int(sid))
                self.slots[key] = self.slots.get(key, False) or real

    def decided(self, t, actions, labels) -> None:
        self._judge_slots()
        self.pending = {}
        for name, a in actions.items():
            op = a.action if isinstance(a, Targeted) else a
            if op in (Action.PickUp, Action.PutDown):
                self.pending[name] = op.name
                self.counts[f"{op.name} issued"] += 1
            if op == Action.PickUp and a.target == (-1, -1):
                self.counts["PickUp at no pixel: " + self._track_state(name)] += 1

    def _track_state(self, name: str) -> str:
        agent = self.agents.get(name)
        sid = getattr(agent, "aimed", None)
        if not hasattr(agent, "refuted"):
            return "not a pixels agent"
        tracks = agent.table.tracks_of(sid) if sid is not None else []
        if not tracks:
            return "no track behind its object"
        return "a refuted track" if tracks[-1] in agent.refuted else "a live track"

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        for name, op in self.pending.items():
            reason = info.get("failed", {}).get(name, "")
            self.counts[f"{op}: " + (kind(reason) if reason else "done")] += 1
            agent = self.agents.get(name)
            if op == "PickUp" and "outside" in reason and getattr(agent, "aimed", None):
                aimed = agent.table.instances[agent.aimed].type
                seg = np.asarray(obs[name]["segmentation"]).ravel()
                ids, n = np.unique(seg, return_counts=True)
                shown = any(self.env.instances.get(int(i)) is not None
                            and self.env.instances[int(i)].type == aimed and c >= MIN_PIXELS
                            for i, c in zip(ids, n, strict=True))  # fmt: skip
                self.counts["PickUp not in view: " + ("an object of its type in view"
                            if shown else "none of its type in view")] += 1  # fmt: skip


def main() -> None:
    args = pixels_probe.arguments(__doc__, "heuristic-none", 4)
    total: Counter = Counter()
    for record, log in pixels_probe.played(args, ActionOutcomes):
        real = sum(log.slots.values())
        log.counts["slots shown: real objects"] += real
        log.counts["slots shown: never an object of their type"] += len(log.slots) - real
        print(f"{record.episode}: success {record.success}, placed {record.reasonable}")
        for k, v in sorted(log.counts.items()):
            print(f"  {v:4d}  {k}")
        total.update(log.counts)
    print("all:")
    for k, v in sorted(total.items()):
        print(f"  {v:4d}  {k}")


if __name__ == "__main__":
    main()
