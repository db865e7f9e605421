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
import hashlib
import io
import json
import math
import time
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR, ROOM_TYPES, load_catalog, load_placement
from maniskill_tidy.perception.detections import detect_objects, resting_place, surface_table
from maniskill_tidy.perception.semantic_map import MapConfig, SemanticMap
from maniskill_tidy.tasks.dataset import write_atomic

FORMAT_VERSION = 1
IMAGE = 64  # visual encoder input side (pixels)
REGIONS = 2  # sub-regions per crop side: the scene encoder answers REGIONS**2 x K queries
MAP_STRIDE = 2  # as the heuristic agents map
DETECTION_NUMERIC = 7  # box (4), distance, image share, lowest point


@dataclass(frozen=True)
class ViewsConfig:
    split: str
    tasks_per_house: int = 2
    every: int = 3
    setting: str = "I"
    seed: int = 0
    houses: int | None = None  # only the split's first N houses (tests, quick looks)


def region_answers(things: list[tuple[str, float, float]], pose, size: int, cell: float):
    """(REGIONS**2, K) booleans: is a thing of category k centred in sub-region r of the crop.

    Uses the crop's convention (``semantic_map.egocentric_crop``): row 0 is the far end ahead
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
        self.maps = {
            a: SemanticMap(public, env.instances, MapConfig(stride=MAP_STRIDE))
            for a in env.agent_names
        }
        self.surfaces = surface_table(public)
        self.places = house_places(house)
        self.room_type = {r.id: r.type for r in house.rooms}

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        u, things = self.env, None
        for a in u.agents:
            if a.stopped:
                continue
            o = obs[a.name]
            self.maps[a.name].update(o)
            if t % self.every == 0:
                if things is None:  # where everything stands now, once per sampled step
                    things = self._things()
                self._sample(a.name, o, things)

    def _things(self) -> list[tuple[str, float, float]]:
        u = self.env
        out = [(f.type, *f.position[:2]) for f in u.house.furniture]
        for oid, st in u.hs.state.items():
            if st.receptacle != "held":
                x, y, _ = u.hs.object_bottom(oid)
                out.append((u.manipulation.types[oid], float(x), float(y)))
        return out

    def _sample(self, name: str, o: dict, things: list[tuple[str, float, float]]) -> None:
        u, catalog = self.env, load_catalog()
        pose = o["pose"]
        room = self.public.room_at(float(pose[0]), float(pose[1]))
        if room is None:
            return
        m = self.maps[name]
        seg = np.asarray(o["segmentation"])
        h, w = seg.shape
        frame_index = len(self.frames["room"])
        seen = np.zeros(len(catalog.categories), dtype=np.float32)
        ids, counts = np.unique(seg, return_counts=True)
        for sid, n in zip(ids, counts, strict=True):
            inst = u.instances.get(int(sid))
            if inst is not None and inst.type in m.categories:
                seen[catalog.category_index(inst.type)] += n / seg.size
        crop = m.local_crop(pose) > 0
        self.frames["rgb"].append(
            cv2.resize(o["rgb"], (IMAGE, IMAGE), interpolation=cv2.INTER_AREA)
        )
        self.frames["seen"].append(seen.astype(np.float16))
        self.frames["crop"].append(np.packbits(crop.reshape(-1)))
        self.frames["room"].append(ROOM_TYPES.index(self.room_type[room]))
        answers = region_answers(things, pose, *_crop_shape(m))
        self.frames["answers"].append(np.packbits(answers.reshape(-1)))
        self.frames["pose"].append(np.asarray(pose, dtype=np.float32))
        held = int(o["held"])
        for d in detect_objects(m.last_frame, u.instances):
            if d.seg_id == held or d.type not in catalog.pickupable:
                continue
            state = u.hs.state[d.object_id]
            if state.receptacle in ("held", "unknown"):
                continue
            rows, cols = np.nonzero(seg == d.seg_id)
            if not len(rows):
                continue
            receptacle, surface, _ = resting_place(self.public, d, self.surfaces)
            if receptacle == FLOOR:
                rest = catalog.receptacles.index(FLOOR)
            elif receptacle:
                f = u.hs.furniture[receptacle]
                rest = catalog.receptacles.index(f.surface(surface).receptacle_type)
            else:
                rest = len(catalog.receptacles)  # rests on nothing the floor plan knows
            misplaced = not u.is_reasonable(d.object_id)
            rec, rooms = reasonable_targets(d.type, self.places)
            self.dets["frame"].append(frame_index)
            self.dets["type"].append(catalog.category_index(d.type))
            self.dets["rest"].append(rest)
            self.dets["numeric"].append(
                [
                    rows.min() / h,
                    cols.min() / w,
                    (rows.max() + 1) / h,
                    (cols.max() + 1) / w,
                    d.distance / 5.0,
                    math.sqrt(d.pixels / (h * w)),
                    d.bottom,
                ]
            )
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


def _init(dataset: str | None, cfg: ViewsConfig) -> None:
    import gymnasium as gym

    import maniskill_tidy  # noqa: F401
    from maniskill_tidy.eval.runner import _die_with_parent

    _die_with_parent()
    env = gym.make(
        "HeteroTidy-v1",
        setting=cfg.setting,
        dataset=dataset,
        split=cfg.split,
        obs_mode="rgb+depth+segmentation",
        reward_mode="none",
    )
    _worker.update(env=env, cfg=cfg)


def _house_views(job: tuple[str, list[int], str]) -> tuple[str, int, int]:
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
    write_atomic(Path(shard), buf.getvalue())
    return house, len(arrays["room"]), len(arrays["det_type"])


def build_views(
    out: Path, dataset: str | None, cfg: ViewsConfig, workers: int = 1, progress: bool = True
) -> dict:
    """Write ``out/SPLIT/house_*.npz`` (resumable per house) and return the manifest."""
    import gymnasium as gym

    import maniskill_tidy  # noqa: F401
    from maniskill_tidy.eval.runner import code_version

    probe = gym.make("HeteroTidy-v1", dataset=dataset, split=cfg.split, obs_mode="none")
    episodes = probe.unwrapped.episodes
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
    probe.close()
    if cfg.houses is not None:
        by_house = dict(sorted(by_house.items())[: cfg.houses])
    directory = Path(out) / cfg.split
    _check_same_config(directory / "manifest.json", dataset_hash, cfg)
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [
        (h, idx, str(directory / f"{h}.npz"))
        for h, idx in sorted(by_house.items())
        if not (directory / f"{h}.npz").exists()
    ]
    started = time.perf_counter()
    bar = tqdm(total=len(by_house), initial=len(by_house) - len(jobs), unit="house",
               desc=f"views {cfg.split}", disable=not progress)  # fmt: skip
    if jobs and workers <= 1:
        _init(dataset, cfg)
        for job in jobs:
            _house_views(job)
            bar.update(1)
        _worker["env"].close()
    elif jobs:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(
            workers, mp_context=get_context("spawn"), initializer=_init, initargs=(dataset, cfg)
        ) as pool:
            for fut in as_completed([pool.submit(_house_views, j) for j in jobs]):
                fut.result()
                bar.update(1)
    bar.close()
    seconds = time.perf_counter() - started if jobs else 0.0
    old = directory / "manifest.json"
    if old.is_file():  # wall time accumulates over the runs that rendered houses
        seconds += json.loads(old.read_text()).get("seconds", 0.0)
    digest = hashlib.sha256()
    frames = detections = 0
    for shard in sorted(directory.glob("house_*.npz")):
        digest.update(shard.name.encode() + hashlib.sha256(shard.read_bytes()).digest())
        with np.load(shard) as z:
            frames += len(z["room"])
            detections += len(z["det_type"])
    manifest = {
        "format_version": FORMAT_VERSION,
        "split": cfg.split,
        "dataset_hash": dataset_hash,
        "houses": len(by_house),
        "tasks_per_house": cfg.tasks_per_house,
        "every": cfg.every,
        "setting": cfg.setting,
        "seed": cfg.seed,
        "frames": frames,
        "detections": detections,
        "views_hash": digest.hexdigest(),
        "seconds": round(seconds, 1),
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def _check_same_config(path: Path, dataset_hash: str, cfg: ViewsConfig) -> None:
    """Refuse to mix shards of two configurations in one folder."""
    if not path.is_file():
        return
    old = json.loads(path.read_text())
    want = {"dataset_hash": dataset_hash, "tasks_per_house": cfg.tasks_per_house,
            "every": cfg.every, "setting": cfg.setting, "seed": cfg.seed}  # fmt: skip
    differ = [k for k, v in want.items() if old.get(k) != v]
    if differ or old.get("houses") != (cfg.houses or old.get("houses")):
        raise ValueError(
            f"{path.parent} holds views built with other settings ({', '.join(differ) or 'houses'}"
            "); remove that folder or pass another --work folder"
        )


def load_views(directory: Path) -> dict[str, np.ndarray]:
    """Every shard of a split folder, concatenated; detection frame indices made global."""
    shards = sorted(Path(directory).glob("house_*.npz"))
    if not shards:
        raise FileNotFoundError(f"no views in {directory}; run `maniskill-tidy train perception`")
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
