"""What the segmenter's frames hold of pickupable objects: the share of pixels they cover, the
share of frames showing one, and their sizes in pixels (docs/pixels.md cites these).

    .venv/bin/python scripts/segmenter_data_stats.py data/segmenter/HeteroTidy-v2/train
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.perception.seg_classes import seg_classes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("split", help="one split's folder of segmenter-data shards")
    args = ap.parse_args()
    classes = seg_classes()
    pixels = on_objects = frames = with_object = 0
    areas: list[int] = []
    for shard in sorted(Path(args.split).glob("house_*.npz")):
        with np.load(shard) as z:
            cls, instance = z["cls"], z["instance"]
        objects = classes.is_pickupable(cls) & (cls > 0)
        pixels += cls.size
        on_objects += int(objects.sum())
        frames += len(cls)
        with_object += int(objects.reshape(len(cls), -1).any(axis=1).sum())
        for k in range(len(cls)):
            ids, counts = np.unique(instance[k][objects[k]], return_counts=True)
            areas.extend(counts[ids > 0].tolist())
    a = np.array(areas)
    print(f"{frames} frames: pickupable objects cover {100 * on_objects / pixels:.2f} % of the "
          f"pixels; {100 * with_object / frames:.0f} % of the frames show one; {len(a)} object "
          f"masks, median {np.median(a):.0f} px, {100 * (a < MIN_PIXELS).mean():.0f} % under "
          f"{MIN_PIXELS} px (the env's visibility)")  # fmt: skip


if __name__ == "__main__":
    main()
