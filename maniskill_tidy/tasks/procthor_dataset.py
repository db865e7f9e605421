"""Datasets from ProcTHOR house files: import, repair or reject, then the usual meta-tasks.

``generate --procthor FILE`` writes the same layout, meta-tasks, starts, manifest and hashes
as the procedural generator (:mod:`maniskill_tidy.tasks.dataset`). House ``n`` of the file
(line ``n + 1``) becomes ``procthor_NNNNN``; its repairs and meta-tasks draw from
``(seed, n)`` alone, so the files do not depend on the number of workers. A house is rejected,
with a one-line reason recorded in the manifest, when it does not import, when no repair rule
makes it sound (:mod:`maniskill_tidy.houses.repair`), or when one of its meta-tasks fails
``validate``'s checks. The kept houses are split in order, train first.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from tqdm import tqdm

from maniskill_tidy.common.parallel import run_jobs
from maniskill_tidy.houses.generator import house_rng
from maniskill_tidy.houses.procthor import read_procthor_houses
from maniskill_tidy.houses.repair import HouseRejected, make_sound
from maniskill_tidy.houses.schema import SCHEMA_VERSION, house_from_dict
from maniskill_tidy.tasks.dataset import (
    SHARD_SIZE,
    SPLITS,
    DatasetError,
    refuse_other_arguments,
    shard_bytes,
    write_atomic,
    write_manifest,
)
from maniskill_tidy.tasks.metatask import SINGLE_FRACTION, generate_meta_tasks, single_schedule
from maniskill_tidy.tasks.validate import check_task

# 2: heights from the floor; 3: L and C counters split; 4: blind corners; 5: a piece that
# overhangs a neighbouring top takes room there; 6: objects named TYPE_N (ProcTHOR's ids, such
# as small|2|1, name the room an object came from, which is where a misplaced one belongs)
IMPORTER_VERSION = "6"
REPAIR_STREAM = 200  # house_rng stream of the repairs' relocations
DEFAULT_WEIGHTS = (4, 1, 1)  # the procedural generator's 80/20/20 proportions


def split_by_weights(n: int, weights: tuple[float, float, float]) -> dict[str, int]:
    """``n`` kept houses in the given proportions; train takes what rounding leaves."""
    if len(weights) != 3 or min(weights) < 0 or sum(weights) <= 0:
        raise ValueError(f"--split {weights}: expected three weights >= 0, not all 0")
    total = sum(weights)
    val, test = (int(n * w / total) for w in weights[1:])
    return {"train": n - val - test, "val": val, "test": test}


def _repair(job: tuple[int, int, dict]) -> tuple[int, dict | None, dict | None, str | None]:
    seed, n, house = job
    try:
        sound, log = make_sound(house_from_dict(house), house_rng(seed, n, stream=REPAIR_STREAM))
    except HouseRejected as e:
        return n, None, None, str(e)
    return n, sound.to_dict(), log.counts(), None


def _tasks(job: tuple[int, int, dict, list[int]]) -> tuple[int, list[dict] | None, str | None]:
    seed, n, house_dict, single = job
    house = house_from_dict(house_dict)
    tasks = generate_meta_tasks(house, seed, n, set(single), from_floor=True)
    for task in tasks:
        problems = check_task(house, task, from_floor=True)
        if problems:
            return n, None, f"meta-task {task.index}: {problems[0].split(': ', 1)[-1]}"
    return n, [t.to_dict() for t in tasks], None


def _map(fn, jobs: list, workers: int, desc: str, progress: bool, ray: str | None) -> list:
    bar = tqdm(total=len(jobs), unit="house", desc=desc, disable=not progress)
    out = []
    with bar:  # closed on an error too, so the error starts a line of its own
        for _, result in run_jobs(jobs, fn, workers, ray=ray, ordered=True):
            out.append(result)
            bar.update()
    return out


def generate_procthor_dataset(
    source: Path,
    out: Path,
    seed: int = 0,
    weights: tuple[float, float, float] = DEFAULT_WEIGHTS,
    limit: int | None = None,
    workers: int = 1,
    progress: bool = True,
    single_fraction: float = SINGLE_FRACTION,
    ray: str | None = None,
) -> dict:
    """Build a dataset in ``out`` from the ProcTHOR houses of ``source`` (at most ``limit``
    of them, from the top of the file); returns the manifest. ``ray``: on Ray actors (see
    :mod:`maniskill_tidy.common.parallel`).

    One function on purpose: the steps (read, import and repair each house, split, write the
    shards, the manifest with every rejection's reason) run in the order the manifest records
    them, and each step's output is the next one's only input."""
    source, out = Path(source), Path(out)
    if not source.is_file():
        raise FileNotFoundError(f"--procthor {source}: no such ProcTHOR house file")
    if limit is not None and limit < 1:
        raise ValueError(f"--houses must be at least 1, got {limit}")
    if not 0.0 <= single_fraction <= 1.0:
        raise ValueError(f"--single-fraction must lie in [0, 1], got {single_fraction}")
    split_by_weights(1, weights)  # refuses bad weights before anything is read
    data = source.read_bytes()
    source_sha = hashlib.sha256(data).hexdigest()
    params = {
        "procthor": source.name,
        "procthor_sha256": source_sha,
        "limit": limit,
        "seed": seed,
        "single_fraction": single_fraction,
        "split_weights": list(weights),
        "importer_version": IMPORTER_VERSION,
        "schema_version": SCHEMA_VERSION,
    }
    params_file = refuse_other_arguments(out, params)

    rejected: dict[int, str] = {}
    problems: list[str] = []
    imported = list(read_procthor_houses(source, problems, limit=limit))
    for p in problems:  # "house N (line N+1): procthor_N: what is wrong"
        rejected[int(p.split()[1])] = "does not import: " + p.split(": ", 2)[-1]
    jobs = [(seed, int(h.id.split("_")[1]), h.to_dict()) for h in imported]
    repaired = {}
    repairs: dict[str, int] = {}
    for n, house, counts, reason in _map(_repair, jobs, workers, "repair", progress, ray):
        if reason is not None:
            rejected[n] = reason
            continue
        repaired[n] = house
        for k, v in counts.items():
            repairs[k] = repairs.get(k, 0) + v
    if not repaired:
        raise DatasetError(
            f"--procthor {source}: no house could be made sound "
            f"({len(rejected)} rejected; first: {next(iter(rejected.values()), 'none read')})"
        )

    order = sorted(repaired)
    schedule = single_schedule(
        [house_from_dict(repaired[n]) for n in order], order, seed, single_fraction
    )
    task_jobs = [(seed, n, repaired[n], sorted(schedule[n])) for n in order]
    tasks = {}
    for n, house_tasks, reason in _map(_tasks, task_jobs, workers, "meta-tasks", progress, ray):
        if reason is not None:
            rejected[n] = reason
        else:
            tasks[n] = house_tasks
    kept = [n for n in order if n in tasks]
    if not kept:
        raise DatasetError(f"--procthor {source}: every house was rejected")

    write_atomic(params_file, json.dumps(params, sort_keys=True).encode())
    splits = split_by_weights(len(kept), weights)
    names, start = [], 0
    for split in SPLITS:
        members = kept[start : start + splits[split]]
        start += splits[split]
        for k, s in enumerate(range(0, len(members), SHARD_SIZE)):
            chunk = members[s : s + SHARD_SIZE]
            name = f"{split}/shard-{k:04d}.json.gz"
            payload = shard_bytes(
                split, seed, [repaired[n] for n in chunk], [t for n in chunk for t in tasks[n]]
            )
            write_atomic(out / name, payload)
            names.append(name)
    manifest_params = {**params, "houses": len(kept), "splits": splits}
    return write_manifest(
        out,
        manifest_params,
        names,
        source={
            "procthor": source.name,
            "sha256": source_sha,
            "houses_read": len(imported) + len(problems),
            "note": "houses imported from ProcTHOR's format (Apache-2.0) and repaired by "
            "maniskill-tidy generate --procthor",
        },
        extra={
            "rejected": [
                {"house": n, "id": f"procthor_{n:05d}", "reason": rejected[n]}
                for n in sorted(rejected)
            ],
            "repairs": repairs,
        },
    )
