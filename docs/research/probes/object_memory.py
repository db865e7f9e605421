"""How often a Place step's target type was already among the agent's own detections. Beside
the model card's object-head accuracy it tells a model that cannot know the target from one
that does not remember it (docs/research/research-log.md, "The learned team: how we got there";
models/decision.py, ``suspects``).

    .venv/bin/python docs/research/probes/object_memory.py data/demos_detection_3tasks/setting_I/val

Reads demonstration shards (what the agents saw and the teacher's labels), nothing else.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.models.decision import pickupable_index


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("demos", type=Path, help="a demos split folder (house_*.npz)")
    args = p.parse_args()
    shards = sorted(args.demos.glob("house_*.npz"))
    if not shards:
        p.error(f"{args.demos}: no house_*.npz shards; expected a demos split folder")
    kind = pickupable_index()
    labelled = own = 0
    for shard in shards:
        with np.load(shard) as z:
            episode, agent, t, target = z["episode"], z["agent"], z["t"], z["object"]
            types: dict[int, set[int]] = {}
            for row, category in zip(z["det_row"], z["det_type"], strict=True):
                types.setdefault(int(row), set()).add(int(kind[category]))
        seen: dict[tuple[int, int], set[int]] = {}
        for row in np.lexsort((t, agent, episode)):  # each agent's steps in order
            so_far = seen.setdefault((int(episode[row]), int(agent[row])), set())
            so_far |= types.get(int(row), set())
            if target[row] >= 0:
                labelled += 1
                own += int(target[row]) in so_far
    print(
        f"{len(shards)} houses, {labelled} steps with a target object; its type was among the "
        f"agent's own detections so far on {own / max(labelled, 1):.3f} of them"
    )


if __name__ == "__main__":
    main()
