"""Why a pixels team loses objects: each misplaced object's fate, written into its run's records.

An observer (``eval/episode.py``) with the benchmark's full access, attached to every pixels run
(``eval --segmentation``): the env renders its segmentation for it, which the runner strips
before any agent sees it. Each step it compares, in every agent's frame, the renderer's mask of
each misplaced object with the masks the agent itself made of that frame (its own label table's
object slots, ``policies/pixels.py``), and each action's outcome with the simulator.

A misplaced object ends in the first of these that holds:

- ``never in view``: no agent frame showed it with ``MIN_PIXELS`` pixels;
- ``never detected``: in view, but no object mask of the agent's covered it (IoU >= 0.5);
- ``wrong type``: only masks of another type covered it;
- ``detected, not picked``: a mask of its type covered it, and no agent picked it up;
- ``picked, not placed`` and ``placed``.

Per object also the most pixels it covered in one agent frame (``largest_view``): an object
never detected though seen large is the segmenter's loss, one only seen far off the team's.

Per object also: how many of an agent's tracks (slots) it was seen as (``tracks`` > 1: one
object split into several), and whether a slot that covered it also covered another object,
misplaced or not, with a quarter of its pixels (``merged``). Per episode: ``false_pickups``,
objects already in place that an agent picked up, and for each (``in_place_picked``) its type
and the type of the slot the agent aimed at (``believed``): its own type means the agent judged
where it rests wrong (or remembered it elsewhere), another that the segmenter's vote misnamed
it, into a type not allowed there.
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS

FATES = (
    "never in view",
    "never detected",
    "wrong type",
    "detected, not picked",
    "picked, not placed",
    "placed",
)
IOU = 0.5  # a mask detects an object it overlaps this much (COCO's AP50 threshold)
MERGED = 0.25  # a mask of which another object covers this share holds two objects


class PixelsLosses:
    """The observer; :meth:`result` is what the episode's record keeps."""

    def start(self, env, team, channel) -> None:
        self.env = env
        self.misplaced = list(env.misplaced)
        self.type_of = {o: env.manipulation.types[o] for o in self.misplaced}
        self.objects = {seg: i.id for seg, i in env.instances.items() if i.kind == "object"}
        self.seg_of = {oid: seg for seg, oid in self.objects.items()}
        self.in_view: set[str] = set()
        self.largest: dict[str, int] = defaultdict(int)  # object -> most pixels in one frame
        self.matched: dict[str, set[bool]] = defaultdict(set)  # object -> {type right?}
        self.slots: dict[str, set] = defaultdict(set)  # object -> {(agent, slot)}
        self.covers: dict[tuple, set[str]] = defaultdict(set)  # (agent, slot) -> objects
        self.held = {a.name: a.held for a in env.agents}
        self.false_pickups = 0
        self.in_place_picked: list[dict] = []
        self.type_by_id = {i.id: i.type for i in env.instances.values() if i.kind == "object"}
        self.agents: dict = {}
        self.truth: dict[str, np.ndarray] = {}

    def executing(self, agents: dict) -> None:
        self.agents = agents

    def observed(self, t: int, obs: dict, info: dict) -> None:
        self.truth = {n: np.asarray(o["segmentation"]) for n, o in obs.items()}

    def decided(self, t: int, actions: dict, labels: dict) -> None:
        """The agents have just made their masks of this step's frames: compare them."""
        for name, agent in self.agents.items():
            seg = getattr(agent, "seg", None)
            if seg is None or name not in actions or name not in self.truth:
                continue
            truth = self.truth[name].reshape(seg.shape)
            for oid in self.misplaced:
                mask = truth == self.seg_of[oid]
                area = int(mask.sum())
                if area < MIN_PIXELS:
                    continue
                self.in_view.add(oid)
                self.largest[oid] = max(self.largest[oid], area)
                ids, counts = np.unique(seg[mask], return_counts=True)
                for sid, inter in zip(ids.tolist(), counts.tolist(), strict=True):
                    inst = agent.table.instances.get(sid)
                    if inst is None or inst.kind != "object":
                        continue
                    slot = seg == sid
                    union = area + int(slot.sum()) - inter
                    if inter / union >= IOU:
                        self.matched[oid].add(inst.type == self.type_of[oid])
                        self.slots[oid].add((name, sid))
                        self.covers[(name, sid)].add(oid)
                        ids_under, n_under = np.unique(truth[slot], return_counts=True)
                        for other, n in zip(ids_under.tolist(), n_under.tolist(), strict=True):
                            if other in self.objects and other != self.seg_of[oid]:
                                if n >= MERGED * slot.sum():  # the mask holds another object
                                    self.covers[(name, sid)].add(self.objects[other])

    def log_step(self, t: int, obs, actions, info, channel, labels) -> None:
        for a in self.env.agents:
            if a.held and a.held != self.held[a.name] and a.held not in self.misplaced:
                self.false_pickups += 1
                agent = self.agents.get(a.name)
                inst = agent.table.instances.get(getattr(agent, "aimed", None)) if agent else None
                self.in_place_picked.append({"type": self.type_by_id.get(a.held),
                                             "believed": inst.type if inst else None})  # fmt: skip
            self.held[a.name] = a.held

    def result(self) -> dict:
        picked = set(self.env.picked)
        placed = {o for o in self.misplaced if self.env.is_reasonable(o)}
        objects = []
        for oid in self.misplaced:
            if oid in placed:
                fate = "placed"
            elif oid in picked:
                fate = "picked, not placed"
            elif True in self.matched[oid]:
                fate = "detected, not picked"
            elif self.matched[oid]:
                fate = "wrong type"
            elif oid in self.in_view:
                fate = "never detected"
            else:
                fate = "never in view"
            merged = any(len(self.covers[s]) > 1 for s in self.slots[oid])
            objects.append({"type": self.type_of[oid], "fate": fate,
                            "tracks": len(self.slots[oid]), "merged": merged,
                            "largest_view": self.largest[oid]})  # fmt: skip
        return {
            "objects": objects,
            "false_pickups": self.false_pickups,
            "in_place_picked": self.in_place_picked,
        }


def summarise(records: list[dict]) -> dict:
    """Fates over a run's records: counts per fate, per type and fate, association errors."""
    fates: Counter = Counter()
    by_type: dict[str, Counter] = defaultdict(Counter)
    split = merged = false_pickups = 0
    views: dict[str, list[int]] = defaultdict(list)  # fate -> largest views
    beliefs: Counter = Counter()  # in place picked up: taken for its own type, or another
    for r in records:
        losses = r.get("pixels") or {}
        false_pickups += losses.get("false_pickups", 0)
        for p in losses.get("in_place_picked", []):  # records before the field have none
            beliefs["its own type" if p["believed"] == p["type"] else "another type"] += 1
        for o in losses.get("objects", []):
            fates[o["fate"]] += 1
            by_type[o["type"]][o["fate"]] += 1
            split += o["tracks"] > 1
            merged += bool(o["merged"])
            if "largest_view" in o:  # records before the field have none
                views[o["fate"]].append(o["largest_view"])
    return {"objects": sum(fates.values()), "fates": {f: fates[f] for f in FATES},
            "by_type": {t: dict(c) for t, c in sorted(by_type.items())},
            "split_into_tracks": split, "merged_with_another": merged,
            "false_pickups": false_pickups, "in_place_picked_as": dict(beliefs),
            "episodes": len(records),
            "median_largest_view": {f: int(np.median(v)) for f, v in views.items()}}  # fmt: skip


def _as_what(beliefs: dict) -> str:
    if not beliefs:
        return ""
    return " (" + ", ".join(f"{n} taken for {b}" for b, n in sorted(beliefs.items())) + ")"


def losses_table(summary: dict, top: int = 12) -> str:
    """Markdown: the fates, then the types that lost the most objects, by why."""
    n = max(summary["objects"], 1)
    lines = [f"{summary['objects']} misplaced objects in {summary['episodes']} episodes; "
             f"{summary['split_into_tracks']} seen as several tracks by one agent, "
             f"{summary['merged_with_another']} in a mask with another object; "
             f"{summary['false_pickups']} objects in place picked up"
             + _as_what(summary.get("in_place_picked_as", {})), "",
             "| fate | objects | share | median of its largest view (px) |",
             "|---|---:|---:|---:|"]  # fmt: skip
    views = summary.get("median_largest_view", {})
    lines += [f"| {f} | {c} | {c / n:.2f} | {views.get(f, '')} |"
              for f, c in summary["fates"].items()]  # fmt: skip
    lost = FATES[1:4]  # what the pixels track adds: seen, yet not detected or not picked
    ranked = sorted(summary["by_type"].items(),
                    key=lambda kv: (-sum(kv[1].get(f, 0) for f in lost), kv[0]))  # fmt: skip
    lines += ["", "| type | objects | " + " | ".join(lost) + " | placed |",
              "|---|---:|" + "---:|" * (len(lost) + 1)]  # fmt: skip
    for t, c in ranked[:top]:
        cells = " | ".join(str(c.get(f, 0)) for f in lost)
        lines.append(f"| {t} | {sum(c.values())} | {cells} | {c.get('placed', 0)} |")
    return "\n".join(lines) + "\n"
