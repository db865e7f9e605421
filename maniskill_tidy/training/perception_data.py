"""Views for the perception modules: what agents' cameras and maps show, with the answers.

The privileged expert plays the first start of some meta-tasks of each house of a split, so
that cameras pass by misplaced and tidy objects alike; every agent fuses its own
:class:`SemanticMap` each step, as a camera-only agent would. Every ``every`` steps each
active agent contributes one *frame*:

- ``rgb``: its colour image, area-averaged to 64 x 64 (the visual encoder's input);
- ``seen``: the share of the image each category covers (the room classifier's "detected
  objects"; segmentation is ground truth, standing in for Mask R-CNN);
- ``crop``: its map's egocentric crop, 20 x 20 x (K + 2) cells of 0.25 m, bit-packed;
- ``room``: the type of the room it stands in (the room classifier's answer);
- ``answers``: for each of the crop's 2 x 2 sub-regions and each category, whether the house
  has a piece of furniture or an object of that type whose centre lies there now (the scene
  encoder's pre-training queries, answered from the house spec and the objects' poses);

and one *detection* per pickupable object in view (at least ``MIN_PIXELS`` pixels):

- features ``sl``: type, image box, distance, sqrt of image share, lowest point, the receptacle
  type under it (back-projected pixels + the floor plan's surfaces, ``perception/detections``);
- answers: ``misplaced`` (D is false where it rests now), the receptacle and room types that
  are reasonable for it (``D``) *and* exist in its house (multi-label), and the D-only sets.

Frames and detections of one house are one ``.npz`` shard, written atomically; a rerun skips
finished houses. ``manifest.json`` holds the dataset hash and a hash of the shards.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.common.parallel import agent_pool
from maniskill_tidy.envs.episodes import EpisodeSet
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog, load_placement
from maniskill_tidy.perception.frame_inputs import DETECTION_NUMERIC, IMAGE, FrameReader
from maniskill_tidy.perception.semantic_map import SemanticMap
from maniskill_tidy.training.house_jobs import (
    check_same_config,
    run_house_jobs,
    shards_digest,
    total_seconds,
    worker_env,
)

FORMAT_VERSION = 1
REGIONS = 2  # sub-regions per crop side: the scene encoder answers REGIONS**2 x K queries


@dataclass(frozen=True)
class ViewsConfig:
    split: str
    tasks_per_house: int = 2
    every: int = 3
    setting: str = "I"
    seed: int = 0
    houses: int | None = None  # only the split's first N houses (tests, quick looks)
    env: str = "HeteroTidy-v1"  # the look the views are rendered in


def region_answers(things: list[tuple[str, float, float]], pose, size: int, cell: float):
    """(REGIONS**2, K) booleans: is a thing of category k centred in sub-region r of the crop.

    Uses the crop's convention (``crops.egocentric_crop``): row 0 is the far end ahead
    of the agent, column 0 its left, the agent at the centre."""
    categories = load_catalog().categories
    out = np.zeros((REGIONS * REGIONS, len(categories)), dtype=bool)
    x, y, rotation = (float(v) for v in pose)
    yaw = math.radians(rotation)
    fwd = np.array([math.cos(yaw), math.sin(yaw)])
    right = np.array([math.sin(yaw), -math.cos(yaw)])
    index = {c: i for i, c in enumerate(categories)}
    per = size / REGIONS
    for kind, tx, ty in things:
        if kind not in index:
            continue
        d = np.array([tx - x, ty - y])
        row = size / 2 - float(d @ fwd) / cell
        col = size / 2 + float(d @ right) / cell
        if 0 <= row < size and 0 <= col < size:
            out[int(row // per) * REGIONS + int(col // per), index[kind]] = True
    return out


def reasonable_targets(object_type: str, house_places: set[tuple[str, str]]):
    """Multi-hot receptacle and room types: D-reasonable, and D-reasonable *and* in the house."""
    catalog, knowledge = load_catalog(), load_placement()
    rec = np.zeros((2, len(catalog.receptacles)), dtype=bool)
    room = np.zeros((2, len(ROOM_TYPES)), dtype=bool)
    for p, r in knowledge.locations(object_type):
        rec[0, catalog.receptacles.index(p)] = room[0, ROOM_TYPES.index(r)] = True
        if (p, r) in house_places:
            rec[1, catalog.receptacles.index(p)] = room[1, ROOM_TYPES.index(r)] = True
    return rec, room


def house_places(house: House) -> set[tuple[str, str]]:
    """(receptacle type, room type) of every surface of the house."""
    rooms = {r.id: r.type for r in house.rooms}
    return {(s.receptacle_type, rooms[f.room]) for f in house.furniture for s in f.surfaces}


class ViewCollector:
    """An episode observer (``eval/episode.py``) that keeps frames and detections."""

    def __init__(self, every: int) -> None:
        self.every = every
        self.frames: dict[str, list] = {k: [] for k in FRAME_KEYS}
        self.dets: dict[str, list] = {k: [] for k in DETECTION_KEYS}

    def start(self, env, team, channel) -> None:
        self.env = env
        house = env.house
        public = dataclasses.replace(house, objects=[])  # what an agent knows (PublicInfo)
        self.public = public
        self.readers = {a: FrameReader(public, env.instances) for a in env.agent_names}
        self.places = house_places(house)
        self.room_type = {r.id: r.type for r in house.rooms}

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        u, things = self.env, None
        active = [a for a in u.agents if not a.stopped]
        # each agent's map is its own: fused on the agent threads, sampled in order here
        pool = agent_pool()
        fuse = lambda a: self.readers[a.name].map.update(obs[a.name])  # noqa: E731
        list(pool.map(fuse, active) if pool is not None else map(fuse, active))
        for a in active:
            reader = self.readers[a.name]
            if t % self.every == 0:
                if things is None:  # where everything stands now, once per sampled step
                    things = self._things()
                self._sample(reader, obs[a.name], things)

    def _things(self) -> list[tuple[str, float, float]]:
        u = self.env
        out = [(f.type, *f.position[:2]) for f in u.house.furniture]
        for oid, st in u.hs.state.items():
            if st.receptacle != "held":
                x, y, _ = u.hs.object_bottom(oid)
                out.append((u.manipulation.types[oid], float(x), float(y)))
        return out

    def _sample(self, reader: FrameReader, o: dict, things: list) -> None:
        pose = o["pose"]
        room = self.public.room_at(float(pose[0]), float(pose[1]))
        if room is None:
            return
        f = reader.read(o, update=False)
        frame_index = len(self.frames["room"])
        self.frames["rgb"].append(f.rgb)
        self.frames["seen"].append(f.seen.astype(np.float16))
        self.frames["crop"].append(np.packbits(f.crop.reshape(-1)))
        self.frames["room"].append(ROOM_TYPES.index(self.room_type[room]))
        answers = region_answers(things, pose, *_crop_shape(reader.map))
        self.frames["answers"].append(np.packbits(answers.reshape(-1)))
        self.frames["pose"].append(np.asarray(pose, dtype=np.float32))
        catalog = load_catalog()
        for i, oid in enumerate(f.det_object):
            if self.env.hs.state[oid].receptacle in ("held", "unknown"):
                continue
            misplaced = not self.env.is_reasonable(oid)
            rec, rooms = reasonable_targets(catalog.categories[f.det_type[i]], self.places)
            self.dets["frame"].append(frame_index)
            self.dets["type"].append(int(f.det_type[i]))
            self.dets["rest"].append(int(f.det_rest[i]))
            self.dets["numeric"].append(f.det_numeric[i])
            self.dets["misplaced"].append(misplaced)
            self.dets["receptacles"].append(rec[1])
            self.dets["rooms"].append(rooms[1])
            self.dets["receptacles_d"].append(rec[0])
            self.dets["rooms_d"].append(rooms[0])

    def arrays(self, house: str) -> dict[str, np.ndarray]:
        catalog = load_catalog()
        out = {"house": np.array(house)}
        empty = {
            "rgb": np.zeros((0, IMAGE, IMAGE, 3), np.uint8),
            "seen": np.zeros((0, len(catalog.categories)), np.float16),
            "numeric": np.zeros((0, DETECTION_NUMERIC), np.float32),
        }
        for key, values in self.frames.items():
            out[key] = np.stack(values) if values else empty.get(key, np.zeros(0))
        for key, values in self.dets.items():
            out["det_" + key] = np.asarray(values) if values else empty.get(key, np.zeros(0))
        out["det_numeric"] = out["det_numeric"].astype(np.float32)
        return out


FRAME_KEYS = ("rgb", "seen", "crop", "room", "answers", "pose")
DETECTION_KEYS = (
    "frame", "type", "rest", "numeric", "misplaced", "receptacles", "rooms",
    "receptacles_d", "rooms_d",
)  # fmt: skip


def _crop_shape(m: SemanticMap) -> tuple[int, float]:
    return m.config.crop_size, m.config.crop_cell


# ---------------------------------------------------------------- building a split's views
_worker: dict = {}


def _init(dataset: str | None, cfg: ViewsConfig):
    env = worker_env(dataset, cfg.setting, cfg.split, cfg.env)
    _worker.update(env=env, cfg=cfg)
    return env.close


def _house_views(job: tuple[str, list[int], str]) -> tuple[str, bytes]:
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.policies.expert import ExpertTeam

    house, indices, shard = job
    env, cfg = _worker["env"], _worker["cfg"]
    collector = ViewCollector(cfg.every)
    for i in indices:
        play_episode(env, ExpertTeam(), i, cfg.seed + i, [collector])
    arrays = collector.arrays(house)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return shard, buf.getvalue()  # written by the driver (a Ray actor may be on another node)


def build_views(
    out: Path,
    dataset: str | None,
    cfg: ViewsConfig,
    workers: int = 1,
    progress: bool = True,
    ray: str | None = None,
) -> dict:
    """Write ``out/SPLIT/house_*.npz`` (resumable per house) and return the manifest."""
    from maniskill_tidy.common.provenance import code_version

    episodes = EpisodeSet.for_setting(dataset, cfg.split, "I")  # the env's default setting
    dataset_hash = episodes.dataset_hash
    by_house: dict[str, list[int]] = {}
    tasks: dict[str, list[str]] = {}
    for i, e in enumerate(episodes.episodes):
        if e.start != 0:
            continue
        seen = tasks.setdefault(e.house_id, [])
        if e.task.id not in seen and len(seen) < cfg.tasks_per_house:
            seen.append(e.task.id)
            by_house.setdefault(e.house_id, []).append(i)
    if cfg.houses is not None:
        by_house = dict(sorted(by_house.items())[: cfg.houses])
    directory = Path(out) / cfg.split
    want = {"dataset_hash": dataset_hash, "tasks_per_house": cfg.tasks_per_house,
            "every": cfg.every, "setting": cfg.setting, "seed": cfg.seed}  # fmt: skip
    if cfg.houses is not None:
        want["houses"] = len(by_house)
    if cfg.env != "HeteroTidy-v1":  # v1 views from before the field existed stay valid
        want["env"] = cfg.env
    check_same_config(directory / "manifest.json", want)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [
        (h, idx, str(directory / f"{h}.npz"))
        for h, idx in sorted(by_house.items())
        if not (directory / f"{h}.npz").exists()
    ]
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"views {cfg.split}", disable=not progress)  # fmt: skip
    seconds = run_house_jobs(jobs, _init, (dataset, cfg), _house_views, workers, bar, ray)
    frames = detections = 0
    for shard in sorted(directory.glob("house_*.npz")):
        with np.load(shard) as z:
            frames += len(z["room"])
            detections += len(z["det_type"])
    manifest = {
        "format_version": FORMAT_VERSION,
        **want,
        "split": cfg.split,
        "houses": len(by_house),
        "frames": frames,
        "detections": detections,
        "views_hash": shards_digest(directory, "house_*.npz"),
        "seconds": total_seconds(directory / "manifest.json", seconds),
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def load_views(directory: Path) -> dict[str, np.ndarray]:
    """Every shard of a split folder, concatenated; detection frame indices made global."""
    shards = sorted(Path(directory).glob("house_*.npz"))
    if not shards:
        raise FileNotFoundError(f"no views in {directory}; run `maniskill-tidy train perception` "
                                "(`--env HeteroTidy-v1` for v1's views)")  # fmt: skip
    parts: dict[str, list] = {}
    offset = 0
    catalog = load_catalog()
    for shard in shards:
        with np.load(shard) as z:
            n = len(z["room"])
            for key in z.files:
                if key == "house":
                    parts.setdefault("frame_house", []).append(np.full(n, str(z["house"])))
                    continue
                value = z[key]
                if key == "det_frame":
                    value = value + offset
                parts.setdefault(key, []).append(value)
            offset += n
    out = {k: np.concatenate([v for v in vs if len(v)] or vs) for k, vs in parts.items()}
    k = len(catalog.categories)
    out["crop"] = np.unpackbits(out["crop"], axis=1)[:, : 20 * 20 * (k + 2)].reshape(
        -1, 20, 20, k + 2
    )
    out["answers"] = np.unpackbits(out["answers"], axis=1)[:, : REGIONS**2 * k].reshape(
        -1, REGIONS**2, k
    )
    return out
