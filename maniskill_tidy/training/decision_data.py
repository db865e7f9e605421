"""Demonstrations with features: what every agent perceived at every step, and a teacher's labels.

A teacher team plays ``starts`` start configurations of every meta-task of a split's houses,
rendering every camera. The paper's teacher is the privileged expert (``policies/expert.py``);
any team that labels its steps with sub-tasks and sub-goals can teach (``teacher``: the
camera-only heuristic teams of ``policies/heuristic.py`` do), which matters because a student
that sees only through its cameras cannot imitate an expert that walks straight to objects
nobody has seen (docs/models.md, "The learned team"). Each agent fuses its own semantic map
and reads its inputs off its own observation with :class:`FrameReader`, the code the learned
team runs at evaluation. Per agent and step (one *row*) a shard stores

- the model's inputs: ``rgb`` (64 x 64), ``seen`` (image share per category), ``crop`` (the map's
  20 x 20 x (K + 2) egocentric crop, bit-packed: 6050 bytes that zlib shrinks to a few hundred,
  smaller than a label image and lossless where a cell holds several categories), ``wide`` (the
  map's coarse 20 x 20 x 3 egocentric layout, uint8 shares: ``crops.wide_layout``), ``pose``,
  ``capability``, ``held`` (type or -1), ``failed`` (its own last action failed), and one
  detection per pickupable object in view (``det_row``, ``det_type``, ``det_rest``,
  ``det_numeric``: the inputs of ``sl``);
- the teacher's labels: the sub-task ``(Explore | Place, o, p, r)`` as ``kind`` (0 Explore, 1
  Place), ``object`` (index in the catalog's pickupable types), ``receptacle`` (catalog
  receptacles), ``room`` (``ROOM_TYPES``), -1 where the sub-task has none; the sub-goal as
  ``dx``, ``dy`` (-4..4), ``drot`` (0..3 quarter turns), ``ope`` (index in ``OPERATIONS``),
  ``stop``; and the low-level ``action`` it took (for the w/o HierDec. ablation). A step in
  which a heuristic agent acts before it has ever labelled one (a side-step at the very start)
  has no row.

With a ``student`` (DAgger, Ross et al. 2011) the student team plays and the teacher only
watches: a :class:`ShadowTeacher` runs the teacher's agents on the same views, on their own
channel, and their labels (and the action each would have taken) are stored for the states the
*student* reaches, the ones behaviour cloning on the teacher's own trajectories never shows it.
``success`` is then the student's.

Rows are ordered by episode, agent, step; ``episode`` indexes the shard's ``episodes`` (JSON:
id, seed, success, length, team). A stopped agent has no rows after its Stop. One ``.npz`` per
house, written atomically; a rerun skips finished houses. ``manifest.json`` holds the dataset
hash, the configuration, counts, the teacher's success, the wall time, the rendering time per
trajectory (each shard records its own, so a crashed run's houses keep theirs) and a hash of
the shards.
"""

from __future__ import annotations

import dataclasses
import io
import json
import time
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.common.parallel import agent_pool
from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.perception.crops import WIDE_SIZE
from maniskill_tidy.perception.frame_inputs import DETECTION_NUMERIC, IMAGE, FrameReader
from maniskill_tidy.policies.base import OPERATIONS, PLACE
from maniskill_tidy.tasks.teams import team as parse_team
from maniskill_tidy.training.house_jobs import (
    check_same_config,
    run_house_jobs,
    shards_digest,
    total_seconds,
    worker_env,
)

FORMAT_VERSION = 2  # 2: rows carry ``wide``
ROW_KEYS = (
    "episode", "agent", "t", "capability", "pose", "held", "failed", "rgb", "seen", "crop",
    "wide", "kind", "object", "receptacle", "room", "dx", "dy", "drot", "ope", "stop", "action",
)  # fmt: skip
DET_KEYS = ("det_row", "det_type", "det_rest", "det_numeric")


@dataclass(frozen=True)
class DemoConfig:
    setting: str = "I"
    split: str = "train"
    starts: int = 1  # start configurations per meta-task (the paper uses all 5)
    tasks: int | None = None  # meta-tasks per house (None: all 10)
    houses: int | None = None  # only the split's first N houses (tests, quick looks)
    seed: int = 0
    teacher: str = "expert"  # the team whose labels are imitated (a registered policy name)
    student: str | None = None  # DAgger: this team plays, the teacher labels (a policy or config)
    env: str = "HeteroTidy-v1"  # the look the demonstrations are rendered in


def subtask_codes(subtask) -> tuple[int, int, int, int]:
    """(kind, object, receptacle, room) indices of a SubTask; -1 where it has none."""
    catalog = load_catalog()

    def index(values, name):
        return values.index(name) if name in values else -1

    return (
        int(subtask.kind == PLACE),
        index(catalog.pickupable, subtask.object_type),
        index(catalog.receptacles, subtask.receptacle_type),
        index(ROOM_TYPES, subtask.room_type),
    )


def subgoal_codes(subgoal) -> tuple[int, int, int, int, int]:
    """(dx, dy, drot quarter turns, ope index, stop) of a SubGoal."""
    return (
        subgoal.dx,
        subgoal.dy,
        subgoal.drot // 90,
        OPERATIONS.index(subgoal.ope),
        int(subgoal.stop),
    )


class ShadowTeacher:
    """The teacher's agents watching another team's episode: each step they observe the same
    views and talk on their own channel; what they would do and their labels are kept, their
    actions are never sent to the env. A heuristic agent reads its cell, heading and held
    object off its observation every step, so it labels states it did not steer into."""

    def __init__(self, teacher: str, seed: int) -> None:
        from maniskill_tidy.policies import make_team

        self.team, self.seed = make_team(teacher), seed

    def start(self, env) -> None:
        from maniskill_tidy.eval.episode import Execution

        self.execution = Execution(self.team, env, self.seed)

    def observed(self, obs: dict, info: dict) -> None:
        self.actions = self.execution.step(obs, info)
        self.labels = self.execution.labels()

    def decided(self, acting: dict) -> tuple[dict, dict]:
        """The teacher's actions and labels for the agents that act this step."""
        keep = [n for n in acting if n in self.actions]
        return {n: self.actions[n] for n in keep}, {n: self.labels[n] for n in keep
                                                   if n in self.labels}  # fmt: skip


class DemoRecorder:
    """An episode observer (``eval/episode.py``): each agent's inputs and the teacher's labels
    (the playing team's own, or a :class:`ShadowTeacher`'s when one is set for the episode)."""

    def __init__(self) -> None:
        self.rows: dict[str, list] = defaultdict(list)
        self.dets: dict[str, list] = defaultdict(list)
        self.episodes: list[dict] = []
        self.shadow: ShadowTeacher | None = None

    def start(self, env, team, channel) -> None:
        self.env = env
        if self.shadow is not None:
            self.shadow.start(env)
        public = dataclasses.replace(env.house, objects=[])  # what an agent knows (PublicInfo)
        self.readers = {a: FrameReader(public, env.instances, wide=True) for a in env.agent_names}
        self.pending: dict[str, tuple] = {}
        self.episode_rows: dict[str, list] = defaultdict(list)
        self.episode_dets: dict[str, list] = defaultdict(list)

    def observed(self, t: int, obs: dict, info: dict) -> None:
        failed = info.get("failed", {})
        names = [a.name for a in self.env.agents if not a.stopped]
        # each agent's reader fuses its own map: independent, so on the agent threads
        pool = agent_pool()
        read = (pool.map if pool is not None else map)(
            lambda n: self.readers[n].read(obs[n]), names
        )  # fmt: skip
        self.pending = {
            n: (f, bool(failed.get(n, ""))) for n, f in zip(names, read, strict=True)
        }  # fmt: skip
        if self.shadow is not None:
            self.shadow.observed(obs, info)

    def decided(self, t: int, actions: dict, labels: dict) -> None:
        if self.shadow is not None:
            actions, labels = self.shadow.decided(actions)
        e = len(self.episodes)
        for i, a in enumerate(self.env.agents):
            if a.name not in actions or a.name not in labels:
                continue
            f, failed = self.pending[a.name]
            subtask, subgoal = labels[a.name]
            action = actions[a.name]
            action = action.action if isinstance(action, Targeted) else Action(int(action))
            self.episode_rows[a.name].append(
                (e, i, t, a.capability, f.pose, f.held, failed, f.rgb, f.seen.astype(np.float16),
                 np.packbits(f.crop.reshape(-1)), f.wide, *subtask_codes(subtask),
                 *subgoal_codes(subgoal), int(action))
            )  # fmt: skip
            self.episode_dets[a.name].append(f)

    def finish(self, record) -> None:
        u = self.env
        for name in u.agent_names:  # agent-major order: each agent's steps are one sequence
            for row, f in zip(self.episode_rows[name], self.episode_dets[name], strict=True):
                index = len(self.rows["episode"])
                for key, value in zip(ROW_KEYS, row, strict=True):
                    self.rows[key].append(value)
                self.dets["det_row"] += [index] * len(f.det_type)
                self.dets["det_type"] += list(f.det_type)
                self.dets["det_rest"] += list(f.det_rest)
                self.dets["det_numeric"] += list(f.det_numeric)
        self.episodes.append(
            {"id": record.episode, "seed": record.seed, "success": record.success,
             "length": record.length, "team": [list(c) for c in u.team],
             "task_kind": record.task_kind, "k": record.k}
        )  # fmt: skip

    def arrays(self, house: str) -> dict[str, np.ndarray]:
        k = len(load_catalog().categories)
        out = {"house": np.array(house), "episodes": np.array(json.dumps(self.episodes))}
        empty = {"rgb": (0, IMAGE, IMAGE, 3), "seen": (0, k), "pose": (0, 4), "capability": (0, 3),
                 "crop": (0, 0), "wide": (0, WIDE_SIZE, WIDE_SIZE, 3),
                 "det_numeric": (0, DETECTION_NUMERIC)}  # fmt: skip
        dtypes = {"rgb": np.uint8, "crop": np.uint8, "wide": np.uint8, "seen": np.float16,
                  "pose": np.float32, "failed": bool, "stop": bool,
                  "det_numeric": np.float32}  # fmt: skip
        for key in ROW_KEYS + DET_KEYS:
            values = self.dets[key] if key in DET_KEYS else self.rows[key]
            dtype = dtypes.get(key, np.int16)
            out[key] = (
                np.asarray(values, dtype=dtype)
                if len(values)
                else np.zeros(empty.get(key, (0,)), dtype)
            )
        out["det_row"] = out["det_row"].astype(np.int32)
        return out


# ---------------------------------------------------------------- building a split's demos
_worker: dict = {}


def env_setting(cfg: DemoConfig):
    """The env's team: the setting's, or the teacher's own (SA plays alone in every setting)."""
    from maniskill_tidy.policies import team_class

    return getattr(team_class(cfg.teacher), "team_override", None) or cfg.setting


def _init(dataset: str | None, cfg: DemoConfig):
    env = worker_env(dataset, env_setting(cfg), cfg.split, cfg.env)
    _worker.update(env=env, cfg=cfg)
    return env.close


def _house_demos(job: tuple[str, list[int], str]) -> tuple[str, bytes]:
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.policies import make_team

    house, indices, shard = job
    env, cfg = _worker["env"], _worker["cfg"]
    recorder = DemoRecorder()
    started = time.perf_counter()
    for i in indices:
        if cfg.student is not None:
            recorder.shadow = ShadowTeacher(cfg.teacher, cfg.seed + i)
        player = make_team(cfg.student or cfg.teacher)
        play_episode(env, player, i, cfg.seed + i, [recorder])
    buf = io.BytesIO()
    seconds = np.array(time.perf_counter() - started)  # this house, one process
    np.savez_compressed(buf, **recorder.arrays(house), seconds=seconds)
    return shard, buf.getvalue()  # written by the driver (a Ray actor may be on another node)


def select_episodes(episodes, cfg: DemoConfig) -> dict[str, list[int]]:
    """House id -> indices of the episodes to play: the first ``tasks`` meta-tasks of each
    house, ``starts`` starts each, the first ``houses`` houses."""
    by_house: dict[str, list[int]] = defaultdict(list)
    tasks: dict[str, list[str]] = defaultdict(list)
    for i, e in enumerate(episodes):
        if e.start >= cfg.starts:
            continue
        seen = tasks[e.house_id]
        if e.task.id not in seen:
            if cfg.tasks is not None and len(seen) >= cfg.tasks:
                continue
            seen.append(e.task.id)
        by_house[e.house_id].append(i)
    houses = sorted(by_house)[: cfg.houses] if cfg.houses is not None else sorted(by_house)
    return {h: by_house[h] for h in houses}


def build_demo_features(
    out: Path,
    dataset: str | None,
    cfg: DemoConfig,
    workers: int = 1,
    progress: bool = True,
    ray: str | None = None,
) -> dict:
    """Write ``out/setting_S/SPLIT/house_*.npz`` (resumable per house); return the manifest."""
    from maniskill_tidy.common.provenance import code_version
    from maniskill_tidy.policies import POLICIES

    if cfg.starts < 1 or (cfg.tasks is not None and cfg.tasks < 1):
        raise ValueError(f"--starts and --tasks must be at least 1, got {cfg.starts}, {cfg.tasks}")
    teachers = sorted(set(POLICIES) - {"hangrcom", "random"})
    if cfg.teacher not in teachers:
        raise ValueError(f"unknown teacher {cfg.teacher!r}; expected one of {teachers}")
    from maniskill_tidy.policies import team_class

    if cfg.student is not None:
        student = team_class(cfg.student)  # an unknown name or config fails here, in one line
        why = getattr(student, "missing_model", lambda team: None)(parse_team(env_setting(cfg)))
        if why:
            raise ValueError(f"student {cfg.student!r}: {why}")
    episodes = EpisodeSet.for_setting(dataset, cfg.split, env_setting(cfg))
    dataset_hash = episodes.dataset_hash
    by_house = select_episodes(episodes.episodes, cfg)
    directory = Path(out) / f"setting_{cfg.setting}" / cfg.split
    want = {"format_version": FORMAT_VERSION, "dataset_hash": dataset_hash, **asdict(cfg)}
    if cfg.student is None:  # folders made before DAgger existed stay valid
        del want["student"]
    if cfg.env == "HeteroTidy-v1":  # and those made before v2 existed
        del want["env"]
    want["teacher_rules"] = getattr(team_class(cfg.teacher), "rules", "")  # its labels' rules
    check_same_config(directory / "manifest.json", want)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [
        (h, idx, str(directory / f"{h}.npz"))
        for h, idx in by_house.items()
        if not (directory / f"{h}.npz").exists()
    ]
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"demos {cfg.setting} {cfg.split}", disable=not progress)  # fmt: skip
    seconds = run_house_jobs(jobs, _init, (dataset, cfg), _house_demos, workers, bar, ray)
    counts = {"trajectories": 0, "successes": 0, "rows": 0, "detections": 0, "bytes": 0}
    timed = {"houses": 0, "trajectories": 0, "seconds": 0.0}  # shards that say how long
    for shard in sorted(directory.glob("house_*.npz")):
        with np.load(shard) as z:
            if "seconds" in z.files:
                timed["houses"] += 1
                timed["trajectories"] += len(json.loads(str(z["episodes"])))
                timed["seconds"] += float(z["seconds"])
            eps = json.loads(str(z["episodes"]))
            counts["trajectories"] += len(eps)
            counts["successes"] += sum(e["success"] for e in eps)
            counts["rows"] += len(z["t"])
            counts["detections"] += len(z["det_row"])
        counts["bytes"] += shard.stat().st_size
    manifest = {
        **want,
        "houses_done": len(list(directory.glob("house_*.npz"))),
        **counts,
        "teacher_success": round(counts["successes"] / max(counts["trajectories"], 1), 4),
        "demos_hash": shards_digest(directory, "house_*.npz"),
        "seconds": total_seconds(directory / "manifest.json", seconds),
        "render_seconds_per_trajectory": round(timed["seconds"] / timed["trajectories"], 2)
        if timed["trajectories"]
        else None,  # one process, over the shards that recorded their time
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def load_demo_features(directory: Path) -> dict[str, np.ndarray]:
    """Every shard of a ``setting_S/SPLIT`` folder, concatenated: rows, detections (their
    ``det_row`` made global) and ``episode`` made a global index; ``crop`` stays packed."""
    shards = sorted(Path(directory).glob("house_*.npz"))
    if not shards:
        raise FileNotFoundError(
            f"no demonstrations in {directory}; run `maniskill-tidy demos --features`"
        )
    parts: dict[str, list] = defaultdict(list)
    episodes: list[dict] = []
    rows = 0
    for shard in shards:
        with np.load(shard) as z:
            for key in ROW_KEYS + DET_KEYS:
                value = z[key]
                if key == "episode":
                    value = value.astype(np.int32) + len(episodes)
                elif key == "det_row":
                    value = value + rows
                parts[key].append(value)
            rows += len(z["t"])
            episodes += json.loads(str(z["episodes"]))
    out = {k: np.concatenate(v) for k, v in parts.items()}
    out["episodes"] = episodes
    return out
