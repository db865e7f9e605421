"""Training data for the object-memory team: the teacher's own job choices.

The object-memory team plays in recording mode (``MemoryTeam(recording=True)``): each agent
chooses its jobs as its teacher, a camera-only heuristic team, does, and at every choice keeps
the candidates it had (``policies/memory_candidates.py``) and which of them the teacher took.
A split's houses are played one shard per house (``house_jobs``: parallel, atomic, a rerun
skips finished houses), the first ``tasks`` meta-tasks of each, ``starts`` starts each.

Shard ``DIR/setting_S/SPLIT/house_NNNNN.npz``, one row per decision: ``episode`` (an index into
the ``episodes`` JSON: id, success, length), ``agent``, ``t``, the candidates' ``kind``,
``type``, ``rest`` (``slots(explore)`` each), ``numeric`` (slots x ``numeric_width(explore)``),
``context`` and ``label`` (the teacher's slot). Choices that match no candidate are counted
(``unmatched``), not kept.
"""

from __future__ import annotations

import io
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.memory import MemoryTeam
from maniskill_tidy.training.decision_data import DemoConfig, select_episodes
from maniskill_tidy.training.house_jobs import (
    check_same_config,
    run_house_jobs,
    shards_digest,
    total_seconds,
)

FORMAT_VERSION = 1
ARRAYS = ("kind", "type", "rest", "numeric", "context", "label", "episode", "agent", "t")
_worker: dict = {}


def _init(cfg: MemoryConfig, config: str, setting: str, split: str):
    from maniskill_tidy.eval.runner import RunConfig, make_env

    env = make_env(RunConfig(cfg.teacher, setting, split, cfg.dataset, env=cfg.env))
    _worker.update(env=env, config=config)
    return env.close


def _house_rows(job: tuple[str, list[int], str]) -> tuple[str, bytes]:
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.policies.memory import memory_team_class

    house, indices, shard = job
    env = _worker["env"]
    team = memory_team_class(_worker["config"])(recording=True)
    rows: dict[str, list] = {k: [] for k in ARRAYS}
    episodes, unmatched = [], 0
    started = time.perf_counter()
    for i in indices:
        team.made.clear()
        record = play_episode(env, team, i, i)  # seed = index, as an eval run's
        episodes.append({"episode": record.episode, "success": record.success,
                         "length": record.length, "reasonable": record.reasonable})  # fmt: skip
        for a, agent in enumerate(team.made):
            for t, r, slot in agent.decisions:
                if slot is None:
                    unmatched += 1
                    continue
                for key, value in (("kind", r.kind), ("type", r.type), ("rest", r.rest),
                                   ("numeric", r.numeric), ("context", r.context),
                                   ("label", slot), ("episode", len(episodes) - 1),
                                   ("agent", a), ("t", t)):  # fmt: skip
                    rows[key].append(value)
    arrays = {k: np.asarray(v) for k, v in rows.items()}
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays, episodes=json.dumps(episodes), unmatched=unmatched,
                        seconds=np.array(time.perf_counter() - started))  # fmt: skip
    return shard, buf.getvalue()


def build_memory_data(
    config: Path, setting: str, split: str, progress: bool = True, workers: int | None = None
) -> Path:
    """Play and record ``split`` (resumable per house); returns its folder, whose
    ``manifest.json`` says what is in it."""
    from maniskill_tidy.common.provenance import code_version

    cfg = MemoryConfig.load(config)
    demos = cfg.train_demos if split == "train" else cfg.val_demos
    select = DemoConfig(setting=setting, split=split, starts=demos.get("starts", 1),
                        tasks=demos.get("tasks"), houses=demos.get("houses"))  # fmt: skip
    episodes = EpisodeSet.for_setting(cfg.dataset, split, setting)
    by_house = select_episodes(episodes.episodes, select)
    directory = Path(cfg.work) / f"setting_{setting}" / split
    chosen = {k: v for k, v in asdict(select).items() if k in ("setting", "split", "starts",
                                                                "tasks", "houses")}  # fmt: skip
    want = {"format_version": FORMAT_VERSION, "dataset_hash": episodes.dataset_hash,
            "teacher": cfg.teacher, "env": cfg.env, "explore": cfg.explore, **chosen}  # fmt: skip
    if MemoryTeam.rules:  # the heuristic agent's rules its choices were played under
        want["teacher_rules"] = MemoryTeam.rules
    check_same_config(directory / "manifest.json", want)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [(h, idx, str(directory / f"{h}.npz")) for h, idx in by_house.items()
            if not (directory / f"{h}.npz").exists()]  # fmt: skip
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"teacher's choices {setting} {split}", disable=not progress)  # fmt: skip
    n = workers or cfg.workers
    seconds = run_house_jobs(jobs, _init, (cfg, str(config), setting, split), _house_rows, n, bar)
    counts = {"trajectories": 0, "successes": 0, "rows": 0, "unmatched": 0}
    for shard in sorted(directory.glob("house_*.npz")):
        with np.load(shard) as z:
            eps = json.loads(str(z["episodes"]))
            counts["trajectories"] += len(eps)
            counts["successes"] += sum(e["success"] for e in eps)
            counts["rows"] += len(z["label"])
            counts["unmatched"] += int(z["unmatched"])
    manifest = {
        **want,
        "houses_done": len(list(directory.glob("house_*.npz"))),
        **counts,
        "teacher_success": round(counts["successes"] / max(counts["trajectories"], 1), 4),
        "data_hash": shards_digest(directory, "house_*.npz"),
        "seconds": total_seconds(directory / "manifest.json", seconds),
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return directory


def load_memory_rows(directory: Path) -> dict[str, np.ndarray]:
    """Every row of a split's shards, in house order (``episode`` made global)."""
    parts: dict[str, list] = {k: [] for k in ARRAYS}
    offset = 0
    for shard in sorted(Path(directory).glob("house_*.npz")):
        with np.load(shard) as z:
            if not len(z["label"]):
                offset += len(json.loads(str(z["episodes"])))
                continue
            for k in ARRAYS:
                parts[k].append(z[k] + offset if k == "episode" else z[k])
            offset += len(json.loads(str(z["episodes"])))
    return {k: np.concatenate(v) for k, v in parts.items()} if parts["label"] else {}
