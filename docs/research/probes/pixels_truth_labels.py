"""How far a pixels team gets when its segmenter is perfect: the same agents, instances, tracks
and pixel targets, fed the renderer's classes (on the segmenter's half-resolution grid, every
pixel fully confident) in place of the segmenter's. Still no instance id: objects are made from
classes and depth as the segmenter's labels are. Beside the same team on ground truth (instance
ids) and on the learned segmenter, in the same episodes: the pixels team's loss split into what
the segmenter costs and what the rest of the pixels pipeline costs. Two arms correct a part of
the segmenter's labels only (``pixels_probe.TruthLabels``): the object pixels, or the types of
what it takes for objects. Each pixels arm also prints its objects' fates (``pixels-losses``).

    .venv/bin/python docs/research/probes/pixels_truth_labels.py --policy memory \\
        --dataset data/tidy120 --episodes 12 [--arms renderer renderer-objects renderer-types]
"""

from __future__ import annotations

import pixels_probe

from maniskill_tidy.eval.pixels_losses import PixelsLosses, summarise


def main() -> None:
    arms = {"ground-truth": "ground truth (ids)", "learned": "learned segmenter",
            "renderer": "renderer's classes", "renderer-objects": "renderer's object pixels",
            "renderer-types": "renderer's types of its object pixels"}  # fmt: skip
    args = pixels_probe.arguments(
        __doc__,
        "memory",
        12,
        lambda ap: ap.add_argument(
            "--arms", nargs="+", choices=list(arms), default=list(arms), help="which arms to play"
        ),
    )
    totals = {}
    learned = args.segmentation
    for key in args.arms:
        name = arms[key]
        args.segmentation = "ground-truth" if key == "ground-truth" else learned
        args.labels = key if key.startswith("renderer") else "segmenter"
        success = placed = k = 0
        fates = []
        for record, losses in pixels_probe.played(args, PixelsLosses):
            success, placed, k = success + record.success, placed + record.reasonable, k + record.k
            print(f"{name}: {record.episode} success {record.success}, placed {record.reasonable}"
                  f"/{record.k}", flush=True)  # fmt: skip
            fates.append({"pixels": losses.result()})
        pixels = args.segmentation != "ground-truth"
        totals[name] = (success, placed, k, summarise(fates)["fates"] if pixels else "")
    for name, (success, placed, k, fates) in totals.items():
        print(f"{name}: Success {success}/{args.episodes}, placed {placed}/{k} {fates}")


if __name__ == "__main__":
    main()
