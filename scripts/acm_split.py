"""Where a paired AvgCom difference comes from: the episodes whose length changed, or the
messages sent per step. ACm is a rate (dimensions received / (length x agents)), so a run
that ends some episodes sooner can raise it while sending less in all, when the steps it cut
carried fewer messages than the rest (for example agents that had stopped).

    .venv/bin/python scripts/acm_split.py eval/results/setting_II/heuristic-broadcast \\
        BEFORE.jsonl   # git show 81e2bef:eval/results/setting_II/heuristic-broadcast/episodes.jsonl

Per group (same length, shorter in A, longer in A): the episodes, their mean ACm difference,
its share of the paired mean over all episodes, and the mean difference in length and in
dimensions received per episode; for the shorter group also the dimensions per agent and step
that B received in the steps A no longer plays.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from maniskill_tidy.eval.metrics import avg_com
from maniskill_tidy.eval.runner import read_records


def records(run: str) -> dict:
    path = Path(run) if run.endswith(".jsonl") else Path(run) / "episodes.jsonl"
    if not path.is_file():
        raise SystemExit(f"{run}: no episodes.jsonl; expected an eval run's folder or a .jsonl")
    return {r.episode: r for r in read_records(path, repair=False)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a")
    parser.add_argument("b")
    args = parser.parse_args()
    a, b = records(args.a), records(args.b)
    shared = [e for e in a if e in b]
    if not shared:
        raise SystemExit(f"{args.a} and {args.b} share no episode; expected runs of one split")
    groups = {"same length": [], "shorter in A": [], "longer in A": []}
    for e in shared:
        d = a[e].length - b[e].length
        groups["same length" if d == 0 else "shorter in A" if d < 0 else "longer in A"].append(e)
    total = np.mean([avg_com(a[e]) - avg_com(b[e]) for e in shared])
    mean_a = np.mean([avg_com(a[e]) for e in shared])
    print(f"ACm A - B over {len(shared)} episodes: {total:+.1f} (A {mean_a:.1f})")
    head = ("group", "episodes", "ACm A-B", "share", "length A-B", "received A-B")
    print(" ".join(f"{h:>{w}}" for h, w in zip(head, (13, 9, 9, 8, 11, 13), strict=True)))
    for name, eps in groups.items():
        if not eps:
            print(f"{name:>13} {0:>9}")
            continue
        dacm = np.mean([avg_com(a[e]) - avg_com(b[e]) for e in eps])
        share = dacm * len(eps) / len(shared)
        dlen = np.mean([a[e].length - b[e].length for e in eps])
        dcomm = np.mean([a[e].comm - b[e].comm for e in eps])
        print(
            f"{name:>13} {len(eps):>9} {dacm:>+9.1f} {share:>+8.1f} {dlen:>+11.1f} {dcomm:>+13.0f}"
        )
    cut = groups["shorter in A"]
    if cut:
        steps = sum((b[e].length - a[e].length) * b[e].agents for e in cut)
        dims = sum(b[e].comm - a[e].comm for e in cut)
        kept = np.mean([avg_com(b[e]) for e in cut])
        print(f"B in the steps A no longer plays: {dims / steps:.1f} dimensions per agent and "
              f"step, against its {kept:.1f} over those episodes")  # fmt: skip


if __name__ == "__main__":
    main()
