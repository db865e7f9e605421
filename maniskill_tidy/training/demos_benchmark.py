"""How long ``demos --features`` takes per trajectory: ``bench --only teams`` (issue 48)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features


def bench_demos(
    houses: int = 2, dataset: str | None = None, env_id: str = "HeteroTidy-v1",
    fresh_process: bool = True,
) -> dict:  # fmt: skip
    """Seconds per trajectory of ``demos --features`` (the expert teaching, every camera drawn,
    every agent's inputs read), one worker, the first meta-task's first start of ``houses``
    train houses: the command's wall time, and the houses' own time (what each further
    trajectory of a long run costs). With ``fresh_process`` it runs in a new interpreter, timed
    from its start, so the command's time holds what ``maniskill-tidy demos`` pays before its
    first trajectory (imports, SAPIEN's set-up, the first pictures), which a process that has
    rendered before has behind it."""
    if fresh_process:
        code = (
            "import json, sys; from maniskill_tidy.training.demos_benchmark import bench_demos; "
            "print(json.dumps(bench_demos(*json.loads(sys.argv[1]), fresh_process=False)))"
        )
        args = json.dumps([houses, dataset, env_id])
        start = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code, args], check=True,
                             capture_output=True, text=True).stdout  # fmt: skip
        wall = time.perf_counter() - start
        child = json.loads(out.strip().splitlines()[-1])
        return {**child, "seconds": wall / child["trajectories"]}  # the interpreter's start too
    cfg = DemoConfig("I", "train", starts=1, tasks=1, houses=houses, env=env_id)
    with tempfile.TemporaryDirectory(prefix="bench-demos-") as out:
        start = time.perf_counter()
        m = build_demo_features(Path(out), dataset, cfg, workers=1, progress=False)
        seconds = time.perf_counter() - start
        houses_s = 0.0
        for shard in Path(out).glob("setting_I/train/*.npz"):
            with np.load(shard) as z:
                houses_s += float(z["seconds"])
    n = m["trajectories"]
    return {"env_id": env_id, "trajectories": n, "seconds": seconds / n,
            "steady_s": houses_s / n, "demos_hash": m["demos_hash"]}  # fmt: skip
