"""When a manipulator dismisses a teammate's report of a misplaced object, could it see it? For
each report a manipulator of a pixels team takes for stale (``HeuristicAgent.dismissed``) that
lies within 0.5 m of a misplaced object: how far the object was from its camera, how many
pixels of the object its frame drew (the renderer's masks, the observer's only), whether any of
its own object masks covered them, the object's fate, and how far the report's point lay from
it. Tells "it looked and its segmenter did not find it" from "the spot looked clear at some
height while the object was hidden".

    .venv/bin/python docs/research/probes/report_dismissals.py --policy memory \\
        --dataset data/tidy120 --episodes 36 --split val
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pixels_probe
from pixels_unpicked import NEAR, Unpicked

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.perception.tracks import camera_position
from maniskill_tidy.policies.pixels import OBJECT_BASE


class Dismissals(Unpicked):
    def start(self, env, team, channel) -> None:
        super().start(env, team, channel)
        self.seen_dismissed: dict[str, int] = {}
        self.events: list[dict] = []

    def decided(self, t, actions, labels) -> None:
        super().decided(t, actions, labels)
        for name, agent in self.agents.items():
            inner = agent.inner
            if not inner.manipulator or name not in self.truth:
                continue
            new = inner.dismissed[self.seen_dismissed.get(name, 0) :]
            self.seen_dismissed[name] = len(inner.dismissed)
            if not new:
                continue
            camera = camera_position(agent.points[2])
            seg = agent.seg
            truth = self.truth[name].reshape(seg.shape)
            for r in new:
                for oid in self.misplaced:
                    bottom = np.asarray(self.env.hs.object_bottom(oid))
                    off = float(np.hypot(*(np.asarray(r.xy) - bottom[:2])))
                    if off >= NEAR:
                        continue
                    mask = truth == self.seg_of[oid]
                    area = int(mask.sum())
                    own = int((seg[mask] >= OBJECT_BASE).sum())
                    dist = float(np.linalg.norm(camera - bottom))
                    self.events.append(
                        {
                            "oid": oid,
                            "type": self.type_of[oid],
                            "same_type": r.type == self.type_of[oid],
                            "area": area,
                            "own": own,
                            "dist": round(dist, 2),
                            "off": round(off, 2),
                            "z": round(float(bottom[2]), 2),
                            "t": t,
                        }
                    )


def main() -> None:
    args = pixels_probe.arguments(__doc__, "memory", 12)
    kinds: Counter = Counter()
    for record, log in pixels_probe.played(args, Dismissals):
        fate = {
            oid: o["fate"] for o, oid in zip(log.result()["objects"], log.misplaced, strict=True)
        }
        for e in log.events:
            drawn = (
                "not drawn"
                if e["area"] < MIN_PIXELS
                else "drawn, own mask on it"
                if e["own"]
                else "drawn, no own mask"
            )
            kinds[(fate[e["oid"]], drawn)] += 1
            print(
                f"{record.episode} {e['type']} ({fate[e['oid']]}): t {e['t']} dist "
                f"{e['dist']} m, report {e['off']} m off, object at z {e['z']}, "
                f"{e['area']} px drawn, {e['own']} "
                f"under own masks, report {'its type' if e['same_type'] else 'another type'}"
            )
    print("dismissals by the object's fate and what the frame drew of it:")
    for (fate, drawn), n in sorted(kinds.items()):
        print(f"  {n:3d}  {fate:22s} {drawn}")


if __name__ == "__main__":
    main()
