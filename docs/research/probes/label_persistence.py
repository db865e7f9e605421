"""How often a demonstration's sub-task label equals the same agent's label one step earlier.

It is the validation accuracy that copying the previous label would score: a model that reads
its own previous sub-task, as CentralComm.'s node does (the teacher's, in training and in the
model card's validation figures), can reach it without choosing anything (docs/models.md, "How each
differs from the paper's description").

    .venv/bin/python docs/research/probes/label_persistence.py \
        data/demos_detection_3tasks/setting_I/val
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HEADS = ("kind", "object", "receptacle", "room")


def persistence(folder: Path) -> dict[str, tuple[float, int]]:
    """Head -> (fraction of labelled steps whose label equals the previous step's, steps)."""
    same = dict.fromkeys(HEADS, 0)
    labelled = dict.fromkeys(HEADS, 0)
    for shard in sorted(folder.glob("house_*.npz")):
        with np.load(shard) as z:
            episode, agent, t = z["episode"], z["agent"], z["t"]
            labels = {k: z[k] for k in HEADS}
        for e, a in {(int(e), int(a)) for e, a in zip(episode, agent, strict=True)}:
            rows = np.flatnonzero((episode == e) & (agent == a))
            rows = rows[np.argsort(t[rows])]
            for k in HEADS:
                y = labels[k][rows]
                has = np.ones(len(y) - 1, bool) if k == "kind" else y[1:] >= 0
                same[k] += int(((y[1:] == y[:-1]) & has).sum())
                labelled[k] += int(has.sum())
    return {k: (same[k] / max(labelled[k], 1), labelled[k]) for k in HEADS}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="a demonstrations folder (setting_S/SPLIT)")
    folder = parser.parse_args().folder
    if not any(folder.glob("house_*.npz")):
        print(f"error: {folder} holds no house_*.npz demonstrations; expected a folder "
              "such as data/demos_detection_3tasks/setting_I/val", file=sys.stderr)  # fmt: skip
        sys.exit(2)
    print("head        same as last step   labelled steps")
    for k, (fraction, n) in persistence(folder).items():
        print(f"{k:<11} {fraction:>17.3f}   {n:>14}")


if __name__ == "__main__":
    main()
