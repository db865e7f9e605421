"""Rendering work split by house: one shard per house, written atomically, a rerun skips the
finished ones; the workers of :mod:`maniskill_tidy.common.parallel` (SAPIEN allows one renderer per
process, so each worker builds its env once); one hash over the shards for the manifest."""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.common.parallel import run_jobs


def worker_env(dataset: str | None, setting: str, split: str, env_id: str = "HeteroTidy-v1"):
    """A worker's env, with every camera image (made once per process); ``env_id`` picks the
    look (HeteroTidy-v1 or -v2)."""
    import gymnasium as gym

    return gym.make(
        env_id,
        setting=setting,
        dataset=dataset,
        split=split,
        obs_mode="rgb+depth+segmentation",
        reward_mode="none",
    )


def run_house_jobs(
    jobs: list,
    init: Callable,
    initargs: tuple,
    work: Callable,
    workers: int,
    bar: tqdm,
    ray: str | None = None,
) -> float:
    """Run ``work(job)`` for every job (in ``workers`` processes or Ray actors, each set up by
    ``init``; see :mod:`maniskill_tidy.common.parallel`) and write the ``(path, bytes)`` it returns
    atomically, here; returns the wall time in seconds."""
    started = time.perf_counter()
    with bar:  # closed on an error too, so the error starts a line of its own
        jobs_done = run_jobs(jobs, work, workers, init=init, initargs=initargs, ray=ray)
        for _, (shard, data) in jobs_done:
            write_atomic(Path(shard), data)
            bar.update(1)
    return time.perf_counter() - started if jobs else 0.0


def total_seconds(manifest: Path, seconds: float) -> float:
    """Wall time accumulated over the runs that rendered houses into one folder."""
    if manifest.is_file():
        seconds += json.loads(manifest.read_text()).get("seconds", 0.0)
    return round(seconds, 1)


UNHASHED = frozenset({"seconds"})  # how long a house took to render: not part of the data


def shards_digest(directory: Path, pattern: str) -> str:
    """One hash over the arrays of every ``.npz`` shard, so that rebuilding a folder from the
    same seed gives the same hash; it skips :data:`UNHASHED` (timing) and the zip container
    (compressor version), which differ between two builds of the same data."""
    digest = hashlib.sha256()
    for shard in sorted(Path(directory).glob(pattern)):
        digest.update(shard.name.encode())
        with np.load(shard) as z:
            for name in sorted(set(z.files) - UNHASHED):
                a = z[name]
                digest.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
                digest.update(hashlib.sha256(np.ascontiguousarray(a).tobytes()).digest())
    return digest.hexdigest()


# What a key was before manifests recorded it: folders made before v2 existed are v1's, and
# v1 folders leave the key out still, so that their manifests read as before; memory folders
# made before MemoryConfig.explore had one explore candidate; folders made before
# ``Team.rules`` were played by a teacher under its first rules.
UNRECORDED = {"env": "HeteroTidy-v1", "explore": 1, "teacher_rules": ""}


def differing(a: dict, b: dict, keys: Iterable[str]) -> list[str]:
    """The keys on which two manifests disagree, a key one leaves out read as ``UNRECORDED``
    reads it."""
    return [k for k in keys if a.get(k, UNRECORDED.get(k)) != b.get(k, UNRECORDED.get(k))]


def check_same_config(manifest: Path, want: dict) -> None:
    """Refuse to mix shards made with two configurations in one folder."""
    if not manifest.is_file():
        return
    old = json.loads(manifest.read_text())
    differ = differing(old, want, [*want, *(k for k in UNRECORDED if k not in want)])
    if differ:
        raise ValueError(
            f"{manifest.parent} holds shards built with other settings ({', '.join(differ)}); "
            "remove that folder or pass another output folder"
        )
