"""Which pickupable types a segmenter finds, type by type: per type, the renderer's objects of
20 px or more on the frames, their median size, the share of their pixels labelled their own
type, the share labelled any pickupable type, and what the rest of their pixels are most often
called. Read beside `pixels-losses`' table by type: a type whose pixels go to a structure or
furniture class is never detected; one whose pixels go to another object type is the wrong type.

    .venv/bin/python docs/research/probes/segmenter_types.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/test --frames 1200
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
import segmenter_probe

from maniskill_tidy.perception.seg_classes import seg_classes


def main() -> None:
    args = segmenter_probe.arguments(__doc__)
    c = seg_classes()
    pickupable = segmenter_probe.pickupable_table()
    frames = segmenter_probe.frames(args)
    model = segmenter_probe.segmenter(args)[0]
    sizes, own, anyobj = defaultdict(list), defaultdict(list), defaultdict(list)
    elsewhere: dict[int, Counter] = defaultdict(Counter)  # type -> labels of its other pixels
    for t, got in segmenter_probe.labelled_objects(model, frames):
        sizes[t].append(len(got))
        own[t].append(float((got == t).mean()))
        anyobj[t].append(float(pickupable[got].mean()))
        elsewhere[t].update(got[got != t].tolist())
    print(f"{len(frames['rgb'])} frames of {args.data}; objects of 20 px or more, by type "
          "(fewest of their pixels labelled their type first)")  # fmt: skip
    print("| type | objects | median px | own type | any object | most of the rest |")
    print("|---|---:|---:|---:|---:|---|")
    for t in sorted(sizes, key=lambda t: np.mean(own[t])):
        rest = elsewhere[t].most_common(2)
        total = sum(elsewhere[t].values()) or 1
        named = ", ".join(f"{c.names[label]} {n / total:.2f}" for label, n in rest)
        print(f"| {c.names[t]} | {len(sizes[t])} | {np.median(sizes[t]):.0f} | "
              f"{np.mean(own[t]):.2f} | {np.mean(anyobj[t]):.2f} | {named} |")  # fmt: skip


if __name__ == "__main__":
    main()
