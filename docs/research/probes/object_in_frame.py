"""Why a pixels agent made no mask of one object in one frame: plays a val episode of memory from
pixels (v2, Setting I) and, at the given steps, for each manipulator whose frame draws the
object, prints how many pixels it covers, the share the floor plan does not explain, the
segmenter's labels on them, and the unexplained parts and agents' masks that overlap it, with
their class and score (a part under ``PLAN_KEEP`` makes no mask), then the tracks near it.
The renderer's masks name the object (the observer's, never an agent's).

    .venv/bin/python docs/research/probes/object_in_frame.py house_00091/task_6/start_3 \\
        30,32,51 Book
"""

from __future__ import annotations

import argparse

import numpy as np
import pixels_probe

from maniskill_tidy.eval.pixels_losses import PixelsLosses
from maniskill_tidy.perception.object_space import object_masks, unexplained
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.policies.pixels import find_masks, frame_arrays, mask_classes

MIN_DRAWN = 20  # pixels of the object a frame must draw to be looked at


class ObjectInFrame(PixelsLosses):
    def __init__(self, steps: set[int], type_name: str) -> None:
        self.steps, self.type_name = steps, type_name
        self.classes = seg_classes()

    def observed(self, t, obs, info) -> None:
        super().observed(t, obs, info)
        self.obs = obs

    def decided(self, t, actions, labels) -> None:
        super().decided(t, actions, labels)
        if t not in self.steps:
            return
        names = self.classes.names
        oid = next(o for o in self.misplaced if self.type_of[o] == self.type_name)
        xy = np.asarray(self.env.hs.object_bottom(oid))[:2]
        for name, agent in self.agents.items():
            if not agent.inner.manipulator:
                continue
            o = self.obs[name]
            rgb, depth = frame_arrays(o)
            truth = self.truth[name].reshape(depth.shape) == self.seg_of[oid]
            if truth.sum() < MIN_DRAWN:
                continue
            lab, probs = agent.segmenter.runtime(rgb[None], depth[None])
            lab, probs = lab[0], probs[0]
            K, E = o["intrinsics"], o["extrinsics"]
            free = unexplained(agent.space, depth, K, E)
            rows, cols = np.nonzero(truth)
            grid = depth.shape[0] // lab.shape[0]
            ids, n = np.unique(lab[rows // grid, cols // grid], return_counts=True)
            votes = [(names[a], int(b)) for a, b in zip(ids, n, strict=True)]
            print(f"t {t} {name}: {int(truth.sum())} px, unexplained {free[truth].mean():.2f}, "
                  f"labels {votes}")  # fmt: skip
            _, objects, _ = mask_classes()
            for m in object_masks(free, depth, lab, probs, objects, MIN_DRAWN):
                if (m.mask & truth).any():
                    r, c = np.nonzero(m.mask)
                    ids, n = np.unique(lab[r // grid, c // grid], return_counts=True)
                    top = sorted(zip(n.tolist(), [names[a] for a in ids], strict=True))[::-1][:3]
                    print(f"  unexplained part: {names[m.cls]} score {m.score:.2f}, "
                          f"{m.area} px, {int((m.mask & truth).sum())} on the object, "
                          f"labelled {top}")  # fmt: skip
            _, found, _ = find_masks(agent.space, lab, probs, depth, K, E,
                                     agent.segmenter.threshold)  # fmt: skip
            for m in found:
                if (m.mask & truth).any():
                    print(f"  agent's mask: {names[m.cls]} score {m.score:.2f}, {m.area} px, "
                          f"{int((m.mask & truth).sum())} on the object")  # fmt: skip
            near = [(names[tr.cls], tr.sightings) for tr in agent.tracker.tracks.values()
                    if np.hypot(*(tr.position[:2] - xy)) < 0.5]  # fmt: skip
            print(f"  tracks within 0.5 m (type, sightings): {near}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("episode", help="a val episode id, e.g. house_00091/task_6/start_3")
    ap.add_argument("steps", help="steps to look at, comma-separated")
    ap.add_argument("type", help="the misplaced object's type")
    ap.add_argument("--dataset", default="data/tidy120")
    args = ap.parse_args()
    steps = {int(s) for s in args.steps.split(",")}
    pixels_probe.play_one(ap, args.episode, [ObjectInFrame(steps, args.type)], split="val",
                          dataset=args.dataset)  # fmt: skip


if __name__ == "__main__":
    main()
