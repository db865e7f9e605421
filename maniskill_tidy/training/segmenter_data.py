"""Frames for the learned segmenter (the pixels track): renders of the project's own houses with
the renderer's masks and types as labels, along the kinds of paths agents take.

Per house of a split, one episode each of the privileged expert, the camera-only heuristic team
and random look-arounds (Setting I: cameras at 0.22, 0.9 and 1.0 m), each from its own
meta-task; every ``every``-th step, every agent's frame is kept: RGB, depth, the class of each
pixel (``perception/seg_classes.py``) and an instance index per pixel (0: none; the same
instance keeps its index across a house's frames, for evaluating instance masks) and its
camera matrices. A house is one ``.npz`` shard written atomically: a killed build resumes at
the next house; one hash over the shards names the data. Train houses train, val houses
select, test houses report.
"""

from __future__ import annotations

import io
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.house_jobs import (
    check_same_config,
    run_house_jobs,
    shards_digest,
    total_seconds,
    worker_env,
)

FORMAT_VERSION = 1
TEAMS = ("expert", "heuristic-none", "random")  # paths that tidy, search, and wander
SETTING = "I"  # one agent per camera height: 0.22, 0.9, 1.0 m
_worker: dict = {}


@dataclass(frozen=True)
class SegDataConfig:
    dataset: str | None
    split: str
    env: str = "HeteroTidy-v2"
    every: int = 6  # keep every agent's frame every this many env steps
    max_steps: int = 120  # of each episode: the first steps show the most of the house
    houses: int | None = None  # the first this many houses of the split (None: all)

    def shard_name(self, house: str) -> str:
        return f"{house}.npz"


def _init(cfg: SegDataConfig):
    env = worker_env(cfg.dataset, SETTING, cfg.split, cfg.env)
    _worker.update(env=env, cfg=cfg)
    return env.close


def _frames(env, team_name: str, index: int, cfg: SegDataConfig) -> list[dict]:
    """Play one episode (seed = index) for at most ``max_steps`` steps; every agent's frame at
    every ``every``-th step, with its labels."""
    from maniskill_tidy.eval.episode import Execution
    from maniskill_tidy.policies import make_team

    u = env.unwrapped
    obs, info = env.reset(seed=index, options={"episode": index})
    execution = Execution(make_team(team_name), u, index)
    classes = seg_classes()
    table = classes.lookup(u.instances)
    out = []
    for t in range(cfg.max_steps):
        if t % cfg.every == 0:
            for a, name in enumerate(u.agent_names):
                o = obs[name]
                seg = np.asarray(o["segmentation"]).reshape(o["rgb"].shape[:2])
                out.append({"rgb": np.asarray(o["rgb"]), "depth": np.asarray(o["depth"]),
                            "cls": classes.labels(seg, table), "seg": seg.astype(np.int64),
                            "intrinsics": np.asarray(o["intrinsics"], dtype=np.float32),
                            "extrinsics": np.asarray(o["extrinsics"], dtype=np.float32),
                            "agent": a, "t": t, "team": team_name,
                            "episode": u.episode.id})  # fmt: skip
        actions = execution.step(obs, info)
        obs, _, terminated, truncated, info = env.step(actions)
        if terminated or truncated:
            break
    return out


def _house(job: tuple[str, dict[str, int], str]) -> tuple[str, bytes]:
    """Render one house's frames into a shard's bytes."""
    house, episodes, shard = job
    env, cfg = _worker["env"], _worker["cfg"]
    started = time.perf_counter()
    frames = [f for team, index in episodes.items() for f in _frames(env, team, index, cfg)]
    # instance index per pixel, shared by the house's frames: 0 none, else 1 + order first seen
    ids: dict[int, int] = {}
    instances = np.zeros((len(frames), *frames[0]["seg"].shape), dtype=np.uint16)
    for i, f in enumerate(frames):
        seg = f["seg"]
        for sid in np.unique(seg[seg > 0]):
            ids.setdefault(int(sid), len(ids) + 1)
            instances[i][seg == sid] = ids[int(sid)]
    depth = np.stack([f["depth"] for f in frames]).astype(np.float32)
    depth_mm = np.round(depth.reshape(depth.shape[:3]) * 1000).clip(0, 65535).astype(np.uint16)
    arrays = {
        "rgb": np.stack([f["rgb"] for f in frames]).astype(np.uint8),
        "depth_mm": depth_mm,
        "cls": np.stack([f["cls"] for f in frames]),
        "instance": instances,
        "intrinsics": np.stack([f["intrinsics"] for f in frames]),
        "extrinsics": np.stack([f["extrinsics"] for f in frames]),
        "agent": np.array([f["agent"] for f in frames], dtype=np.int8),
        "t": np.array([f["t"] for f in frames], dtype=np.int16),
        "team": np.array([TEAMS.index(f["team"]) for f in frames], dtype=np.int8),
    }
    meta = {"episodes": episodes, "instance_ids": {v: k for k, v in ids.items()}}
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays, meta=json.dumps(meta),
                        seconds=np.array(time.perf_counter() - started))  # fmt: skip
    return shard, buf.getvalue()


def house_episodes(
    dataset: str | None, split: str, houses: int | None
) -> tuple[dict[str, dict[str, int]], str]:
    """House -> {team: episode index}: the first start of its first three meta-tasks, one per
    team, so that no two teams replay the same mess."""
    from maniskill_tidy.envs.episodes import EpisodeSet

    episodes = EpisodeSet.for_setting(dataset, split, SETTING)
    firsts: dict[str, list[int]] = {}
    for i, e in enumerate(episodes.episodes):
        if e.start == 0:
            firsts.setdefault(e.house_id, []).append(i)
    chosen = sorted(firsts)[:houses] if houses is not None else sorted(firsts)
    out = {}
    for h in chosen:
        if len(firsts[h]) < len(TEAMS):
            raise ValueError(f"{h}: {len(firsts[h])} meta-tasks; expected {len(TEAMS)} or more")
        out[h] = dict(zip(TEAMS, firsts[h], strict=False))
    return out, episodes.dataset_hash


def build_segmenter_data(
    cfg: SegDataConfig, out: Path, workers: int = 1, progress: bool = True
) -> dict:
    """Render ``cfg.split``'s houses into ``out`` (resumable per house); returns the manifest."""
    from maniskill_tidy.common.provenance import code_version

    by_house, dataset_hash = house_episodes(cfg.dataset, cfg.split, cfg.houses)
    out = Path(out)
    classes = seg_classes()
    want = {"format_version": FORMAT_VERSION, "dataset_hash": dataset_hash,
            "classes": classes.digest, "setting": SETTING, "teams": list(TEAMS),
            **{k: v for k, v in asdict(cfg).items() if k != "dataset"}}  # fmt: skip
    check_same_config(out / "manifest.json", want)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(h, eps, str(out / cfg.shard_name(h))) for h, eps in by_house.items()
            if not (out / cfg.shard_name(h)).exists()]  # fmt: skip
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"segmenter frames {cfg.env} {cfg.split}", disable=not progress)  # fmt: skip
    seconds = run_house_jobs(jobs, _init, (cfg,), _house, workers, bar)
    frames = 0
    for shard in sorted(out.glob("house_*.npz")):
        with np.load(shard) as z:
            frames += len(z["agent"])
    manifest = {
        **want,
        "class_names": list(classes.names),
        "houses_done": len(list(out.glob("house_*.npz"))),
        "frames": frames,
        "data_hash": shards_digest(out, "house_*.npz"),
        "seconds": total_seconds(out / "manifest.json", seconds),
        "code_version": code_version(),
    }
    write_atomic(out / "manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest
