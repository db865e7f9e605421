"""Why a pixels team never shows an object it had in view: for each misplaced object some agent
frame showed with ``MIN_PIXELS`` pixels, the furthest its masks got in any frame. No mask of
its type covered half of it (on the segmenter's grid: too few cells, merged into a larger
mask of its type, or labelled otherwise), a mask did but scored under the keep threshold
(confidence times the depth-contrast gate), it was kept but shown in no slot (a track not
yet confirmed, refuted, or no depth), or shown. Per stage, all types and thin ones (as
``depth_contrast.py``). With ``--labels renderer`` every mask's confidence is 1, so a mask
under the threshold is the gate's doing alone.

    .venv/bin/python docs/research/probes/pixels_unshown.py --policy memory \\
        --dataset data/tidy120 --episodes 36 --labels renderer
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
import pixels_probe
from depth_contrast import thin_types

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.pixels_losses import IOU, PixelsLosses
from maniskill_tidy.policies import pixels

STAGES = ("no mask of its type", "a mask under the threshold", "kept, shown in no slot", "shown")


def capture_masks() -> None:
    """Keep each pixels agent's scored object masks of its last frame (``agent.probe_masks``)."""
    captured: list = []
    score, frame = pixels.scored_by_relief, pixels.PixelsAgent._frame

    def scored(masks, depth, classes):
        out = score(masks, depth, classes)
        captured[:] = out
        return out

    def framed(self, obs, step):
        seg = frame(self, obs, step)
        self.probe_masks = list(captured)
        return seg

    pixels.scored_by_relief, pixels.PixelsAgent._frame = scored, framed


class Unshown(PixelsLosses):
    def start(self, env, team, channel) -> None:
        super().start(env, team, channel)
        self.stage: dict[str, int] = defaultdict(int)  # object -> furthest stage index
        self.best: dict[str, float] = defaultdict(float)  # object -> best score of its masks

    def decided(self, t, actions, labels) -> None:
        super().decided(t, actions, labels)
        for name, agent in self.agents.items():
            masks = getattr(agent, "probe_masks", None)
            if masks is None or name not in self.truth or agent.seg is None:
                continue
            seg, g = agent.seg, agent.grid
            truth = self.truth[name].reshape(seg.shape)
            keep = min(pixels.KEEP_THRESHOLD, agent.segmenter.threshold)
            classes = agent.table.classes
            for oid in self.misplaced:
                full = truth == self.seg_of[oid]
                if full.sum() < MIN_PIXELS:
                    continue
                cells = full[::g, ::g]
                stage = 0
                for m in masks:
                    if classes.names[m.cls] != self.type_of[oid] or not cells.any():
                        continue
                    if (m.mask & cells).sum() >= 0.5 * cells.sum():
                        self.best[oid] = max(self.best[oid], m.score)
                        stage = max(stage, 2 if m.score >= keep else 1)
                if stage == 2 and self._shown(agent, seg, full):
                    stage = 3
                self.stage[oid] = max(self.stage[oid], stage)

    def _shown(self, agent, seg, full) -> bool:
        ids, counts = np.unique(seg[full], return_counts=True)
        for sid, inter in zip(ids.tolist(), counts.tolist(), strict=True):
            inst = agent.table.instances.get(sid)
            if inst is not None and inst.kind == "object":
                if inter / (full.sum() + (seg == sid).sum() - inter) >= IOU:
                    return True
        return False


def main() -> None:
    args = pixels_probe.arguments(__doc__, "memory", 12)
    capture_masks()
    thin = thin_types()
    counts = {"all": Counter(), "thin": Counter()}
    for record, log in pixels_probe.played(args, Unshown):
        for oid in log.misplaced:
            if oid not in log.in_view:
                continue
            stage = STAGES[log.stage[oid]]
            counts["all"][stage] += 1
            if log.type_of[oid] in thin:
                counts["thin"][stage] += 1
            if log.stage[oid] < 3:
                print(f"{record.episode} {oid}: {stage} (best score {log.best[oid]:.2f}, "
                      f"largest view {log.largest[oid]} px)", flush=True)  # fmt: skip
    for group, c in counts.items():
        print(f"{group} objects in view: " + ", ".join(f"{s} {c[s]}" for s in STAGES))


if __name__ == "__main__":
    main()
