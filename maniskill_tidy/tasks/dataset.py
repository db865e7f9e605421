"""Dataset files: seeded houses and their meta-tasks, in gzipped JSON shards with a manifest.

Layout of a dataset directory::

    manifest.json               schema version, seed, splits, sha256 of every shard, dataset hash
    train/shard-0000.json.gz    {"houses": [...], "tasks": [...]} for up to SHARD_SIZE houses
    val/...  test/...

House ``i`` is generated from ``(seed, i)`` alone, and split membership is by index (train
first), so files are byte-identical for the same arguments whatever the number of workers.
Shards are written atomically; a rerun with the same arguments keeps finished shards (resume).
"""

from __future__ import annotations

import gzip
import io
import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from maniskill_tidy.common.files import sha256, write_atomic
from maniskill_tidy.common.memory import collector_paused
from maniskill_tidy.common.parallel import run_jobs
from maniskill_tidy.houses.generator import generate_house
from maniskill_tidy.houses.schema import SCHEMA_VERSION, House, house_from_dict
from maniskill_tidy.tasks.metatask import (
    SINGLE_FRACTION,
    MetaTask,
    generate_meta_tasks,
    single_schedule,
)

SHARD_SIZE = 50
SPLITS = ("train", "val", "test")
GENERATOR_VERSION = "3"  # 2: misplacements no higher than the manipulator camera; 3: Single mix


class DatasetError(RuntimeError):
    pass


def split_counts(n_houses: int, counts: tuple[int, int, int] | None = None) -> dict[str, int]:
    """Houses per split: explicit counts, or the paper's 80/20/20 proportions."""
    if counts is not None:
        if sum(counts) != n_houses or min(counts) < 0:
            raise ValueError(f"split counts {counts} must be >= 0 and add up to {n_houses}")
        return dict(zip(SPLITS, counts, strict=True))
    val = test = n_houses // 6
    return {"train": n_houses - val - test, "val": val, "test": test}


def dumps_gz(payload: dict) -> bytes:
    """Deterministic gzip: fixed mtime, no file name, sorted keys."""
    raw = json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=6) as f:
        f.write(raw)
    return buf.getvalue()


def _make_shard(args: tuple[int, str, int, int, float, bool]) -> tuple[str, int, int, bytes]:
    seed, split, start, stop, single_fraction, secret = args
    built = [generate_house(seed, i) for i in range(start, stop)]
    schedule = single_schedule(built, list(range(start, stop)), seed, single_fraction)
    houses, tasks = [], []
    for i, house in zip(range(start, stop), built, strict=True):
        houses.append(dict(house.to_dict(), seed=None) if secret else house.to_dict())
        tasks += [t.to_dict() for t in generate_meta_tasks(house, seed, i, schedule[i])]
    recorded = SECRET if secret else seed
    return split, stop - start, len(tasks), shard_bytes(split, recorded, houses, tasks)


SECRET = "secret"  # what a secret split's files say in place of its seed
SECRET_SEED_BITS = 32  # a secret seed below 2**32 could be found by trying them all
SECRET_SEED_VARIABLE = "MANISKILL_TIDY_SECRET_SEED"


def secret_seed(path: str | None) -> int:
    """The seed of a split kept out of every file: from ``path`` or the environment variable
    :data:`SECRET_SEED_VARIABLE`, as a challenge server keeps its test split."""
    import os

    if path is not None:
        try:
            text, where = Path(path).read_text().strip(), path
        except OSError as e:
            raise ValueError(f"--secret-seed-file {path}: {e.strerror}") from None
    else:
        text, where = os.environ.get(SECRET_SEED_VARIABLE, ""), SECRET_SEED_VARIABLE
        if not text:
            raise ValueError(f"{SECRET_SEED_VARIABLE} is not set; expected a secret seed")
    try:
        seed = int(text)
    except ValueError:
        raise ValueError(f"{where}: expected an integer seed, got {text[:20]!r}") from None
    if seed < 2**SECRET_SEED_BITS:
        raise ValueError(
            f"{where}: a secret seed below 2**{SECRET_SEED_BITS} can be found by trying them "
            "all; make one with `python -c 'import secrets; print(secrets.randbits(64))'`"
        )
    return seed


def shard_bytes(split: str, seed: int | str, houses: list[dict], tasks: list[dict]) -> bytes:
    return dumps_gz(
        {
            "schema_version": SCHEMA_VERSION,
            "split": split,
            "seed": seed,
            "houses": houses,
            "tasks": tasks,
        }
    )


def generate_dataset(
    out: Path,
    n_houses: int,
    seed: int,
    counts: tuple[int, int, int] | None = None,
    workers: int = 1,
    progress: bool = True,
    single_fraction: float = SINGLE_FRACTION,
    ray: str | None = None,
    secret: bool = False,
) -> dict:
    """Generate (or resume) a dataset in ``out``; returns the manifest.

    ``single_fraction``: the share of meta-tasks meant to be Single (default the paper's);
    ``ray``: build the shards on Ray actors (see :mod:`maniskill_tidy.common.parallel`);
    ``secret``: write no seed anywhere (the manifest and shards say "secret", houses have
    none); only a digest of it in ``.generate.json``, so that a resume needs the same one."""
    out = Path(out)
    if n_houses < 1:
        raise ValueError(f"--houses must be at least 1, got {n_houses}")
    if not 0.0 <= single_fraction <= 1.0:
        raise ValueError(f"--single-fraction must lie in [0, 1], got {single_fraction}")
    splits = split_counts(n_houses, counts)
    params = {
        "houses": n_houses,
        "seed": SECRET if secret else seed,
        "single_fraction": single_fraction,
        "splits": splits,
        "generator_version": GENERATOR_VERSION,
        "schema_version": SCHEMA_VERSION,
    }
    # a resume needs the same secret: only its digest is kept, beside the shards
    arguments = dict(params, secret_sha256=sha256(str(seed).encode())) if secret else params
    params_file = refuse_other_arguments(out, arguments)
    write_atomic(params_file, json.dumps(arguments, sort_keys=True).encode())

    jobs, start = [], 0
    for split in SPLITS:
        n = splits[split]
        for k, s in enumerate(range(start, start + n, SHARD_SIZE)):
            jobs.append(
                (
                    f"{split}/shard-{k:04d}.json.gz",
                    (seed, split, s, min(s + SHARD_SIZE, start + n), single_fraction, secret),
                )
            )
        start += n
    todo = [(name, a) for name, a in jobs if not (out / name).exists()]
    bar = tqdm(
        total=n_houses,
        unit="house",
        desc="generate",
        disable=not progress,
        initial=n_houses - sum(a[3] - a[2] for _, a in todo),
    )
    names = {a: name for name, a in todo}
    with bar:  # closed on an error too, so the error starts a line of its own
        for a, result in run_jobs([a for _, a in todo], _make_shard, workers, ray=ray):
            write_atomic(out / names[a], result[3])
            bar.update(result[1])
    return write_manifest(out, params, [name for name, _ in jobs])


PROCEDURAL_SOURCE = (
    "maniskill-tidy generate (procedural houses; knowledge derived from ProcTHOR, Apache-2.0)"
)


def refuse_other_arguments(out: Path, params: dict) -> Path:
    """The file that records a dataset's arguments; a rerun resumes only with the same ones."""
    params_file = out / ".generate.json"
    if params_file.exists() and json.loads(params_file.read_text()) != params:
        raise DatasetError(
            f"{out} holds a dataset made with other arguments "
            f"({params_file.read_text().strip()}); use another --out"
        )
    return params_file


def write_manifest(
    out: Path,
    params: dict,
    names: list[str],
    source: str | dict = PROCEDURAL_SOURCE,
    extra: dict | None = None,
) -> dict:
    """Hash every shard and write ``manifest.json``; ``extra`` adds keys (what an importer
    rejected and why)."""
    files = {}
    for name in names:
        data = (out / name).read_bytes()
        payload = json.loads(gzip.decompress(data))
        files[name] = {
            "sha256": sha256(data),
            "houses": len(payload["houses"]),
            "tasks": len(payload["tasks"]),
        }
    manifest = {
        **params,
        "files": files,
        "tasks": {
            s: sum(f["tasks"] for n, f in files.items() if n.startswith(s + "/")) for s in SPLITS
        },
        "dataset_hash": sha256(
            "".join(f"{n}:{f['sha256']}\n" for n, f in sorted(files.items())).encode()
        ),
        "source": source,
        **(extra or {}),
    }
    write_atomic(
        out / "manifest.json", (json.dumps(manifest, indent=1, sort_keys=True) + "\n").encode()
    )
    return manifest


@dataclass
class Dataset:
    """A dataset split loaded into memory: houses by id and their meta-tasks."""

    root: Path
    split: str
    manifest: dict
    houses: dict[str, House]
    tasks: list[MetaTask]

    def episodes(self, setting: str) -> Iterator[tuple[MetaTask, int]]:
        """Every (meta-task, start index): 10 x 5 per house, as in the paper."""
        for task in self.tasks:
            for j in range(len(task.starts[setting])):
                yield task, j


def read_manifest(root: Path) -> dict:
    path = Path(root) / "manifest.json"
    if not path.is_file():
        raise DatasetError(
            f"{root} has no manifest.json; is it a dataset made by `maniskill-tidy generate`?"
        )
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path} is not valid JSON: {e}") from None
    if not isinstance(manifest.get("files"), dict):
        raise DatasetError(f"{path}: no 'files' table; regenerate the dataset")
    if manifest.get("schema_version") != SCHEMA_VERSION:
        raise DatasetError(
            f"{path}: schema_version {manifest.get('schema_version')!r}, "
            f"expected {SCHEMA_VERSION!r}"
        )
    return manifest


def read_shard(path: Path, expected_sha256: str | None = None) -> dict:
    """A shard's payload; with ``expected_sha256``, refuses a file whose bytes differ."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise DatasetError(f"{path}: listed in the manifest but missing") from None
    if expected_sha256 is not None and sha256(data) != expected_sha256:
        raise DatasetError(
            f"{path}: sha256 differs from the manifest (the file was changed or truncated); "
            "regenerate the dataset or run `maniskill-tidy validate`"
        )
    try:
        payload = json.loads(gzip.decompress(data))
    except (OSError, EOFError, gzip.BadGzipFile) as e:
        raise DatasetError(f"{path}: not a complete gzip file ({e})") from None
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path}: not valid JSON inside the gzip ({e})") from None
    for key in ("houses", "tasks"):
        if not isinstance(payload.get(key), list):
            raise DatasetError(f"{path}: missing the list {key!r}")
    return payload


def load_dataset(root: Path, split: str = "train") -> Dataset:
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; expected one of {SPLITS}")
    root = Path(root)
    manifest = read_manifest(root)
    houses: dict[str, House] = {}
    tasks: list[MetaTask] = []
    with collector_paused():
        for name in sorted(manifest["files"]):
            if not name.startswith(split + "/"):
                continue
            payload = read_shard(root / name, manifest["files"][name].get("sha256"))
            for h in payload["houses"]:
                house = house_from_dict(h)
                houses[house.id] = house
            tasks += [MetaTask.from_dict(t) for t in payload["tasks"]]
    return Dataset(root, split, manifest, houses, tasks)
