"""Run a team over a split's episodes: resumable, parallel, one JSONL line per episode.

A run directory holds ``run.json`` (what was asked: policy, setting, split, dataset hash, seed,
episode selection), ``episodes.jsonl`` (one :class:`EpisodeRecord` per finished episode, appended
and flushed as each one ends) and ``summary.json`` (metrics, written atomically at the end).
Rerunning the same command skips the episodes already in the JSONL file, so an interrupted run
resumes where it stopped and never counts an episode twice; a torn last line is cut off; a run
directory made with different arguments is refused. Episode ``i`` always gets seed
``seed + i``, whatever the number of workers, so results do not depend on it.

Which episodes (``RunConfig.episodes``): ``"standard"``, the benchmark's protocol, plays the
first start of every meta-task of the split (200 episodes on the 120-house test split);
``"all"`` plays every start (the paper's 1000); a number ``N`` an evenly spread subset.
"""

from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.agent_files import resolve
from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.common.parallel import auto_workers, run_jobs
from maniskill_tidy.common.provenance import code_version
from maniskill_tidy.envs.registration import ENV_ID
from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.metrics import EpisodeRecord, summarize
from maniskill_tidy.eval.pixels_losses import PixelsLosses
from maniskill_tidy.policies import make_team, team_class
from maniskill_tidy.policies.channel import CENTRAL
from maniskill_tidy.policies.pixels import PIXELS_OBSERVATION, PIXELS_PIPELINE, pixels_perception

RECORD_MODES = ("none", "failures", "all")
ALL_IMAGES = "rgb+depth+segmentation"


@dataclass(frozen=True)
class RunConfig:
    policy: str
    setting: str
    split: str
    dataset: str | None  # None: the env's shipped default dataset
    episodes: str | int = "standard"  # "standard", "all" or a number (see the top)
    seed: int = 0
    task_type: str = "all"
    # the version, i.e. the look (VERSIONS in maniskill_tidy). v1 here, not the commands'
    # default look (v2): a run file from before "env" existed ran in v1 (``RunFile``)
    env: str = ENV_ID
    # the perception track: "ground-truth" segmentation, or "learned" (the pixels track with
    # the look's shipped segmenter, agents/segmenter-v1 or -v2) or a segmenter's folder
    segmentation: str = "ground-truth"

    @property
    def pixels(self) -> bool:
        return self.segmentation != "ground-truth"

    def segmenter(self) -> str:
        """The folder of the segmenter a pixels run uses."""
        return str(segmenter_folder(self.segmentation, self.env))

    def env_kwargs(self, images: bool | str) -> dict:
        """``images``: True for every camera image, False for the team's own observation
        mode (``Team.observations``, "none" for teams that ignore images), or an obs_mode."""
        team_cls = team_class(self.policy)
        if isinstance(images, str):
            mode = images
        elif images:
            mode = ALL_IMAGES  # the runner strips what a pixels team may not see
        elif self.pixels:  # the runner strips the segmentation; the losses observer reads it
            mode = ALL_IMAGES
        else:
            mode = team_cls.observations if team_cls.needs_images else "none"
        pixels = {"targets": "pixels"} if self.pixels else {}
        return {
            **pixels,
            "setting": getattr(team_cls, "team_override", None) or self.setting,
            "dataset": self.dataset,
            "split": self.split,
            "task_type": self.task_type,
            "obs_mode": mode,
            "reward_mode": "none",
        }


def segmenter_folder(segmentation: str, env: str) -> Path:
    """``"learned"`` is the look's shipped segmenter (agents/segmenter-v2 for HeteroTidy-v2);
    anything else names a segmenter's folder."""
    if segmentation == "learned":
        return resolve(f"agents/segmenter-{env.rsplit('-', 1)[1]}")
    return resolve(segmentation)


def row_segmenter(name: str, env: str) -> Path:
    """The segmenter folder a pixels row's name stands for, as it is now (the inverse of
    ``run_name``'s suffix: ``memory-v2-pixels`` is the look's own, ``memory-v2-pixels-segmenter-v1``
    agents/segmenter-v1); the leaderboard checks a row's weights against it."""
    folder = name.split("-pixels-", 1)[1] if "-pixels-" in name else None
    return segmenter_folder(f"agents/{folder}" if folder else "learned", env)


def run_name(cfg: RunConfig) -> str:
    """The team's name; a run on another env version than v1 is its own row (``expert-v2``),
    and so is a pixels run (``memory-v2-pixels``; with another look's segmenter, its folder's
    name after it: ``memory-v2-pixels-segmenter-v1``)."""
    name = team_class(cfg.policy).name
    name = name if cfg.env == ENV_ID else f"{name}-{cfg.env.rsplit('-', 1)[1]}"
    if cfg.segmentation == "learned":
        return f"{name}-pixels"
    return f"{name}-pixels-{Path(cfg.segmentation).name}" if cfg.pixels else name


def make_run_team(cfg: RunConfig):
    """The team a run plays: in the pixels track, wrapped to see through the segmenter."""
    team = make_team(cfg.policy)
    if cfg.pixels:
        from maniskill_tidy.policies.pixels import PixelsTeam

        team = PixelsTeam(team, cfg.segmenter())
    return team


def run_dir(out: Path, cfg: RunConfig) -> Path:
    return Path(out) / "eval" / "results" / f"setting_{cfg.setting}" / run_name(cfg)


# ---------------------------------------------------------------------- one episode
def make_env(cfg: RunConfig, images: bool | str = False):
    import gymnasium as gym

    return gym.make(cfg.env, **cfg.env_kwargs(images))


def run_episode(env, team, index: int, seed: int, recorder=None) -> EpisodeRecord:
    """Play episode ``index`` of the env's split with ``team``; log it if ``recorder`` is given.
    A pixels team's record keeps what became of each misplaced object (``pixels_losses``)."""
    observers = [recorder] if recorder is not None else []
    if not getattr(team, "pixels", False):
        return play_episode(env, team, index, seed, observers)
    losses = PixelsLosses()
    record = play_episode(env, team, index, seed, [*observers, losses])
    return dataclasses.replace(record, pixels=losses.result())


# ---------------------------------------------------------------------- workers
_worker: dict = {}


def _init_worker(cfg: RunConfig, images: bool, record: str, out: str):
    _worker.update(cfg=cfg, env=make_env(cfg, images), team=make_run_team(cfg))
    _worker.update(record=record, out=out, images=images)
    return _close_worker


def _close_worker() -> None:
    _worker["env"].close()
    _worker.clear()


def _work(index: int) -> EpisodeRecord:
    cfg, env, team = _worker["cfg"], _worker["env"], _worker["team"]
    recorder = None
    if _worker["record"] == "all":
        recorder = _recorder(cfg, Path(_worker["out"]))
    return run_episode(env, team, index, cfg.seed + index, recorder)


def _recorder(cfg: RunConfig, out: Path):
    from maniskill_tidy.recording.episode_log import EpisodeRecorder

    name = team_class(cfg.policy).name
    return EpisodeRecorder(out / "recordings" / f"setting_{cfg.setting}" / name)


def _record_failures(cfg: RunConfig, records: list[EpisodeRecord], indices: dict, out: Path):
    """Play failed episodes again with images and a recorder (runs are deterministic)."""
    failed = [r for r in records if not r.success]
    if not failed:
        return
    env, team = make_env(cfg, images=True), make_run_team(cfg)
    for r in tqdm(failed, desc="recording failures", unit="ep"):
        run_episode(env, team, indices[r.episode], r.seed, _recorder(cfg, out))
    env.close()


# ---------------------------------------------------------------------- a run
PROTOCOLS = ("standard", "all")


def episode_spec(value: str | int | None) -> str | int:
    """``--episodes``: "standard", "all" or a positive number; anything else is refused."""
    if value is None:
        return "standard"
    if isinstance(value, str) and value in PROTOCOLS:
        return value
    try:
        n = int(value)
    except (TypeError, ValueError):
        raise ValueError(
            f"--episodes {value!r}: expected standard, all or a positive number"
        ) from None
    if n <= 0 or str(n) != str(value).strip():
        raise ValueError(f"--episodes must be a positive whole number, got {value!r}")
    return n


def select(starts: list[int], spec: str | int | None) -> list[int]:
    """Indices of the episodes to play, given each episode's start number (see the top)."""
    spec = episode_spec(spec)
    n_total = len(starts)
    if spec == "standard":
        return [i for i, s in enumerate(starts) if s == 0]
    if spec == "all" or spec >= n_total:
        return list(range(n_total))
    return sorted({int(i) for i in np.linspace(0, n_total, spec, endpoint=False)})


def read_records(path: Path, repair: bool = True) -> list[EpisodeRecord]:
    """Records in a JSONL file; a torn last line (an interrupted write) is left out, and with
    ``repair`` (the runner, before it resumes) cut off the file. Readers of another process's
    run (compare, leaderboard) pass ``repair=False``: that line may still be being written."""
    if not path.exists():
        return []
    records, good = [], 0
    with open(path, "rb") as f:
        data = f.read()
    for line in data.splitlines(keepends=True):
        try:
            if not line.endswith(b"\n"):
                raise ValueError("torn line")
            records.append(EpisodeRecord.from_dict(json.loads(line)))
        except (ValueError, TypeError):
            break
        good += len(line)
    if repair and good < len(data):
        with open(path, "r+b") as f:
            f.truncate(good)
    return records


@contextmanager
def exclusive(directory: Path):
    """Hold ``directory/.lock`` for the run; a second run on the same folder is refused."""
    with open(directory / ".lock", "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(
                f"{directory} is being written by another eval run; wait for it to end or "
                "pass another --out"
            ) from None
        lock.write(f"{os.getpid()}\n")
        lock.flush()
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def evaluate(
    cfg: RunConfig,
    out: Path = Path("."),
    workers: int | None = 1,
    record: str = "none",
    progress: bool = True,
    images: bool = False,
    ray: str | None = None,
) -> dict:
    """Run (or resume) an evaluation and write its summary; returns the summary.

    ``ray``: play the episodes on Ray actors ("local" or a cluster's address, see
    :mod:`maniskill_tidy.common.parallel`) instead of ``workers`` local processes; ``workers``
    None: one per core, no more than there are episodes to play."""
    team_cls = team_class(cfg.policy)  # a one-line error for an unknown policy
    if record not in RECORD_MODES:
        raise ValueError(f"--record must be one of {RECORD_MODES}, got {record!r}")
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.tasks.teams import team as parse_team

    setting = getattr(team_cls, "team_override", None) or cfg.setting
    members = parse_team(setting)
    missing = getattr(team_cls, "missing_model", lambda team: None)(members)
    if missing:  # before the run folder is made: nothing half-written
        raise FileNotFoundError(missing)
    segmentation = "ground-truth"
    if cfg.pixels:
        from maniskill_tidy.models.checkpoints import served_sha256

        if team_cls.privileged or not team_cls.needs_images:
            raise ValueError(
                f"--segmentation {cfg.segmentation}: {cfg.policy} does not look "
                "through cameras; the pixels track is for camera-only teams"
            )
        segmentation = f"learned:{served_sha256(cfg.segmenter())}"  # checks the files
    # As the env does: the smallest setting that fits the team gives the starts (for SA, one
    # manipulator, that is Setting I's first start).
    episodes = EpisodeSet(cfg.dataset, cfg.split, cfg.task_type, None, members)
    chosen = select([e.start for e in episodes.episodes], cfg.episodes)
    ids = {episodes.get(i).id: i for i in chosen}

    directory = run_dir(out, cfg)
    directory.mkdir(parents=True, exist_ok=True)
    with exclusive(directory):  # one run per results folder: two would both append
        config = {
            **{k: v for k, v in cfg.__dict__.items() if k != "segmentation" or cfg.pixels},
            "dataset_hash": episodes.dataset_hash,
            "episode_count": len(chosen),
        }
        model = getattr(team_cls, "model_hash", lambda team: None)(members)
        if model is not None:  # a learned team: resuming with other weights is refused below
            config["model_hash"] = model
        if cfg.pixels:  # and a pixels run's segmenter, once retrained: its episodes would mix
            config["segmenter_sha256"] = segmentation.split(":", 1)[1]
            config["pixels_pipeline"] = PIXELS_PIPELINE  # and how its agents read the labels
        if getattr(team_cls, "rules", ""):  # and a team's rules changed since its first runs
            config["rules"] = team_cls.rules
        run = RunFile(directory, config)
        images = images or record == "all"  # else the team's own observations
        jsonl = directory / "episodes.jsonl"
        records = [r for r in read_records(jsonl) if r.episode in ids]
        done = {r.episode for r in records}
        todo = [i for i in chosen if episodes.get(i).id not in done]
        if workers is None:
            workers = auto_workers(len(todo))
        bar = tqdm(
            total=len(chosen),
            initial=len(done),
            desc=f"{cfg.policy} setting {cfg.setting} {cfg.split}",
            unit="ep",
            disable=not progress,
        )
        with open(jsonl, "a") as sink, bar:  # the bar closes on an error too
            jobs = run_jobs(todo, _work, workers, init=_init_worker,
                            initargs=(cfg, images, record, str(out)), ray=ray)  # fmt: skip
            for _, r in jobs:
                run.episode_done()  # before the episode's line: a killed session's share stays
                sink.write(json.dumps(r.to_dict(), sort_keys=True) + "\n")
                sink.flush()
                os.fsync(sink.fileno())
                records.append(r)
                bar.update(1)
                bar.set_postfix(success=f"{np.mean([x.success for x in records]):.3f}")
        if record == "failures":
            _record_failures(cfg, records, ids, out)
        summary = _summary(cfg, team_cls, members, episodes.dataset_hash, config, run, records,
                           workers, ray, images)  # fmt: skip
        summary["segmentation"] = segmentation
        write_atomic(directory / "summary.json", json.dumps(summary, indent=1).encode())
        return summary


def _summary(
    cfg: RunConfig, team_cls, members, dataset_hash: str, config: dict, run: RunFile,
    records: list[EpisodeRecord], workers: int, ray: str | None, images: bool,
) -> dict:  # fmt: skip
    """``summary.json``: what ran, on what, with which code, and the metrics."""
    return {
        "policy": run_name(cfg),
        "env": cfg.env,
        "protocol": cfg.episodes
        if isinstance(cfg.episodes, str)
        else f"{cfg.episodes} evenly spread episodes",
        "setting": cfg.setting,
        "split": cfg.split,
        "team": [list(c) for c in members],
        "communication": getattr(team_cls, "communication", "none"),
        "privileged": team_cls.privileged,
        "perception": _perception(cfg, team_cls),
        "dataset": cfg.dataset or "default (shipped with the package)",
        "dataset_hash": dataset_hash,
        "model_hash": config.get("model_hash"),  # a learned team's weights; None otherwise
        "rules": config.get("rules", ""),  # the team's decision rules (Team.rules)
        **({"pixels_pipeline": config["pixels_pipeline"]} if cfg.pixels else {}),
        **run.versions(),
        "seed": cfg.seed,
        "episodes": len(records),
        "metrics": summarize(records),
        "wall_seconds": run.info["wall_seconds"],  # summed over sessions that ran episodes
        "workers": workers,
        "ray": ray,  # None: local processes; "local" or the cluster's address
        "obs_mode": PIXELS_OBSERVATION if cfg.pixels else cfg.env_kwargs(images)["obs_mode"],
        "episode_seconds_mean": round(float(np.mean([r.seconds for r in records])), 3),
        "central_endpoint": CENTRAL if getattr(team_cls, "central", False) else None,
    }


def _perception(cfg: RunConfig, team_cls) -> str:
    """What the team's agents perceive with (in the pixels track, as ``PixelsTeam`` says it)."""
    own = getattr(team_cls, "perception", "")
    return pixels_perception(own) if cfg.pixels else own


class RunFile:
    """A run's ``run.json``: its arguments, checked against the run it resumes, and the wall
    time and code versions, summed over the sessions that played its episodes."""

    def __init__(self, directory: Path, config: dict) -> None:
        self.path = directory / "run.json"
        self.version = code_version()  # of the code that runs the episodes, taken before
        before = json.loads(self.path.read_text()) if self.path.exists() else None
        self.before_versions = [self.version]
        self.wall = 0.0
        if before is not None:
            informative = ("dataset", "code_versions")  # a moved dataset with the same hash is fine
            # runs from before a field existed ran with its default (v1 before "env")
            defaults = {f.name: f.default for f in fields(RunConfig)}
            diff = {
                k: (before.get(k, defaults.get(k)), v)
                for k, v in config.items()
                if k not in informative and before.get(k, defaults.get(k)) != v
            }
            if diff:
                raise ValueError(
                    f"{directory} holds a run with other arguments {diff} (before, now); "
                    "pass another --out or delete that directory"
                )
            self.before_versions = before.get("code_versions", []) or [self.version]
            self.wall = before.get("wall_seconds", 0.0)
        self.info = {**config, "code_versions": self.before_versions, "wall_seconds": self.wall}
        self._write()
        self.started = time.perf_counter()

    def _write(self) -> None:
        write_atomic(self.path, json.dumps(self.info, indent=1, sort_keys=True).encode())

    def episode_done(self) -> None:
        self.info["wall_seconds"] = round(self.wall + time.perf_counter() - self.started, 1)
        self.info["code_versions"] = list(dict.fromkeys([*self.before_versions, self.version]))
        self._write()

    def versions(self) -> dict:
        versions = self.info["code_versions"]
        return {
            "code_version": versions[-1],
            "code_versions": versions,  # every version that ran part of this run (resumed runs)
            "mixed_code_versions": len(versions) > 1,
        }
