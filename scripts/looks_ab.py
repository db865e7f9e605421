"""v2's cost before and after an asset change, in one run: v2 / v1 env steps per second (fast
quality, 224 px, ``envs/looks_benchmark.py``) for the code at ``--before`` (a temporary git
worktree) and the checkout, alternated per setting and repeat so that both see the same machine.

    python scripts/looks_ab.py --before f26a965~1 --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBE = (
    "import json, sys\n"
    "from maniskill_tidy.envs.looks_benchmark import bench_looks\n"
    "r = bench_looks(sys.argv[1], 'fast')\n"
    "print(json.dumps({'v1': r['v1_per_s'], 'v2': r['v2_per_s']}))\n"
)


def measure(code: Path, setting: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(code))
    out = subprocess.run([sys.executable, "-c", PROBE, setting], env=env, cwd=code,
                         capture_output=True, text=True, check=True)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", required=True, help="the commit to compare the checkout with")
    p.add_argument("--repeats", type=int, default=2)
    args = p.parse_args()
    tree = Path(tempfile.mkdtemp(prefix="looks-ab-")) / "before"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(tree),
                    args.before], check=True)  # fmt: skip
    runs: dict[tuple[str, str], list[float]] = {}
    try:
        for rep in range(args.repeats):
            for setting in ("I", "II"):
                for arm, code in (("before", tree), ("now", ROOT)):
                    r = measure(code, setting)
                    runs.setdefault((arm, setting), []).append(r["v2"] / r["v1"])
                    rates = f"v1 {r['v1']:.1f}/s v2 {r['v2']:.1f}/s v2/v1 {r['v2'] / r['v1']:.3f}"
                    print(f"repeat {rep + 1} setting {setting} {arm:>6}: {rates}", flush=True)
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)])
    print(f"\nv2 / v1, median of {args.repeats} (before = {args.before}):")
    for setting in ("I", "II"):
        b, n = (statistics.median(runs[(a, setting)]) for a in ("before", "now"))
        print(f"  setting {setting}: before {b:.3f}  now {n:.3f}  now / before {n / b:.3f}")


if __name__ == "__main__":
    main()
