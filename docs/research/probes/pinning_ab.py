"""Two eval workers pinned to their own cores against unpinned, alternately (issue 48).

    python docs/research/probes/pinning_ab.py heuristic-none hangrcom --rounds 2

Each round runs ``bench_workers`` (eval with 1 then 2 local processes on the same 6 Setting I
test episodes, as ``bench --only teams`` does) once unpinned and once with
``TIDY_PIN_WORKERS=1``, in alternating order, and prints the 2-worker / 1-worker ratios (whole
command and steady state). The machine's speed moves between runs, hence rounds. Nothing is
written.
"""

from __future__ import annotations

import argparse
import os

from maniskill_tidy.eval.team_benchmark import bench_workers


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("teams", nargs="+")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()
    print("team              pinned  whole  steady  cores 1 / 2")
    for r in range(args.rounds):
        for team in args.teams:
            for pin in ("0", "1") if r % 2 == 0 else ("1", "0"):
                os.environ["TIDY_PIN_WORKERS"] = pin
                w = bench_workers(team, dataset=args.dataset)
                pinned = "yes" if pin == "1" else "no"
                ratios = f"{w['two_over_one']:5.2f}  {w['steady']:6.2f}"
                cores = f"{w['cores_one']:.2f} / {w['cores_two']:.2f}"
                print(f"{team:17s} {pinned:6s}  {ratios}  {cores}", flush=True)


if __name__ == "__main__":
    main()
