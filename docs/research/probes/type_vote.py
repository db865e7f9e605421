"""Does one type per object region help the segmenter's masks? Val mask AP50 over the
pickupable types with instances made as agents make them (on the network's grid), with and
without a vote that gives each object region one type first (`vote_types`, here: rejected,
val AP50 0.265 -> 0.215 for agents/experiments/segmenter-v2-wp075), and the best-F1 threshold
of each.

    .venv/bin/python docs/research/probes/type_vote.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --frames 400
"""

from __future__ import annotations

import numpy as np
import segmenter_probe
from scipy import ndimage

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.perception.instances import depth_edges
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import instance_pairs


def vote_types(
    labels: np.ndarray, probabilities: np.ndarray, depth: np.ndarray, first: int
) -> np.ndarray:
    """``labels`` with one type per object: each connected region of pixels labelled with any
    type from ``first`` on (the pickupable ones), split where the depth jumps, takes the type
    of most confidence summed over it (pixels on a depth edge join the region nearest them).
    A small segmenter often calls parts of one object by two or three types (a paper towel
    roll a soap bottle and a plate); split by type, each part is a mask too small or of the
    wrong type, where the whole is one object of its likeliest type."""
    objects = labels >= first
    if not objects.any():
        return labels
    inner = objects & ~depth_edges(depth)
    regions, n = ndimage.label(inner)
    if n == 0:
        return labels
    if (objects & ~inner).any():  # edge pixels join the nearest region
        _, (iy, ix) = ndimage.distance_transform_edt(regions == 0, return_indices=True)
        regions = np.where(objects, regions[iy, ix], 0)
    at = regions > 0
    votes = np.bincount(regions[at].astype(np.int64) * 256 + labels[at],
                        weights=probabilities[at], minlength=(n + 1) * 256)  # fmt: skip
    winner = votes.reshape(n + 1, 256).argmax(1).astype(labels.dtype)
    out = labels.copy()
    out[at] = winner[regions[at]]
    return out


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    classes = seg_classes()
    pickupable = [i for i in range(len(classes.names)) if classes.is_pickupable(i)]
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    shape = frames["rgb"].shape[1:3]

    def voted(labels, probs, depth):
        return vote_types(labels, probs, depth, classes.first_pickupable)

    for vote in (False, True):
        pairs = instance_pairs(model, frames, voted if vote else None)[0]
        ap50 = mask_ap(pairs, pickupable, shape, ignore_below=MIN_PIXELS)
        best = score_threshold(pairs, pickupable, shape, ignore_below=MIN_PIXELS)
        print(
            f"vote={vote}: AP50 {ap50['AP50']:.3f} AP {ap50['AP']:.3f} small "
            f"{ap50['AP_small']:.3f} predicted {ap50['predicted']}; best F1 {best['f1']:.3f} "
            f"(P {best['precision']:.2f} R {best['recall']:.2f} at {best['threshold']:.3f})"
        )


if __name__ == "__main__":
    main()
