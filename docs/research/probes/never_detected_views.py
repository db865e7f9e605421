"""How large the objects no agent's mask covered were ever seen: for each pixels row, the
objects of fate "never detected" (``pixels-losses``) counted by their largest view in one agent
frame (pixels of the 224 x 224 frame). Reads the rows' records, plays nothing.

    python docs/research/probes/never_detected_views.py eval/results/setting_*/*-v2-pixels
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.eval.runner import read_records

EDGES = (0, 100, 200, 400, 800, 1600)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", nargs="+", help="pixels rows' folders")
    args = ap.parse_args()
    names = [f"{a}-{b}" for a, b in zip(EDGES[:-1], EDGES[1:], strict=True)] + [f">={EDGES[-1]}"]
    print("| row | never detected | " + " | ".join(names) + " | under 200 px |")
    print("|---|---:|" + "---:|" * (len(names) + 1))
    for row in args.rows:
        views = np.array([o["largest_view"]
                          for r in read_records(Path(row) / "episodes.jsonl", repair=False)
                          for o in (r.pixels or {}).get("objects", [])
                          if o["fate"] == "never detected"])  # fmt: skip
        counts = np.histogram(views, [*EDGES, np.inf])[0]
        under = int((views < 200).sum())
        print(f"| {row} | {len(views)} | " + " | ".join(map(str, counts)) + f" | {under} |")


if __name__ == "__main__":
    main()
