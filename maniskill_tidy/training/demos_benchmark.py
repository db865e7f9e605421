"""How long ``demos --features`` takes per trajectory: ``bench --only teams`` (issue 48)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features


def bench_demos(houses: int = 2, dataset: str | None = None, env_id: str = "HeteroTidy-v1") -> dict:
    """Seconds per trajectory of ``demos --features`` (the expert teaching, every camera drawn,
    every agent's inputs read), one process, the first meta-task's first start of ``houses``
    train houses: the command's wall time (start-up included), and the houses' own time (what
    each further trajectory of a long run costs)."""
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
