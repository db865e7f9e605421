"""How far a pixels team gets when its segmenter is perfect: the same agents, instances, tracks
and pixel targets, fed the renderer's classes (on the segmenter's half-resolution grid, every
pixel fully confident) in place of the segmenter's. Still no instance id: objects are made from
classes and depth as the segmenter's labels are. Beside the same team on ground truth (instance
ids) and on the learned segmenter, in the same episodes: the pixels team's loss split into what
the segmenter costs and what the rest of the pixels pipeline costs.

    .venv/bin/python docs/research/probes/pixels_truth_labels.py --policy memory \\
        --dataset data/tidy120 --episodes 12
"""

from __future__ import annotations

import pixels_probe


class Nothing:
    """No observer: the episode's record is enough."""


def main() -> None:
    args = pixels_probe.arguments(__doc__, "memory", 12)
    totals = {}
    learned = args.segmentation
    arms = (("ground truth (ids)", "ground-truth", "segmenter"),
            ("learned segmenter", learned, "segmenter"),
            ("renderer's classes", learned, "renderer"))  # fmt: skip
    for name, args.segmentation, args.labels in arms:
        success = placed = k = 0
        for record, _ in pixels_probe.played(args, Nothing):
            success, placed, k = success + record.success, placed + record.reasonable, k + record.k
            print(f"{name}: {record.episode} success {record.success}, placed {record.reasonable}"
                  f"/{record.k}")  # fmt: skip
        totals[name] = (success, placed, k)
    for name, (success, placed, k) in totals.items():
        print(f"{name}: Success {success}/{args.episodes}, placed {placed}/{k}")


if __name__ == "__main__":
    main()
