"""How long a fresh process takes to make the env and draw its first pictures (issue 48).

    python docs/research/probes/startup_probe.py [--runs 3] [--dataset data/tidy120]

Every run is a new interpreter, as an evaluation worker, a ``demos`` worker or a CLI command
is: it times the imports, ``gym.make`` (ManiSkill's set-up, the first reset and its pictures)
and a reset and step after it, in both looks, and prints the medians over the runs. SAPIEN
computes its BRDF table at a process's first picture unless the cameras are lent the cached
one (``sim/brdf_lut.py``), and in v2 prefilters the environment map unless it is loaded from
the cache (``sim/environment_map.py``). To compare commits, run it with ``PYTHONPATH`` set to
another checkout. Nothing is written (the caches aside).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

from tqdm import tqdm

CHILD = """
import json, sys, time
start = time.perf_counter()
import gymnasium as gym
import maniskill_tidy.envs  # noqa: F401
imported = time.perf_counter()
env = gym.make(sys.argv[1], dataset=sys.argv[2] or None)
made = time.perf_counter()
env.reset(seed=0)
env.step(env.action_space.sample())
stepped = time.perf_counter()
print(json.dumps({"import": imported - start, "make": made - imported, "step": stepped - made}))
"""


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--dataset", default="data/tidy120")
    args = p.parse_args()
    jobs = [(env_id, k) for k in range(args.runs) for env_id in ("HeteroTidy-v1", "HeteroTidy-v2")]
    times: dict[str, list[dict]] = {}
    for env_id, _ in tqdm(jobs, desc="fresh processes"):
        out = subprocess.run([sys.executable, "-c", CHILD, env_id, args.dataset], check=True,
                             capture_output=True, text=True).stdout  # fmt: skip
        times.setdefault(env_id, []).append(json.loads(out.strip().splitlines()[-1]))
    print(f"median of {args.runs} fresh processes, seconds")
    print(f"{'env':<16}{'imports':>9}{'gym.make':>10}{'reset+step':>12}{'total':>8}")
    for env_id, runs in times.items():
        med = {k: statistics.median(r[k] for r in runs) for k in ("import", "make", "step")}
        total = statistics.median(sum(r.values()) for r in runs)
        print(f"{env_id:<16}{med['import']:>9.2f}{med['make']:>10.2f}{med['step']:>12.2f}"
              f"{total:>8.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
