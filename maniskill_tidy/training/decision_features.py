"""The decision model's inputs for every demonstration row, computed once: the frozen perception
model's features (sv, sm, and fd, fp of the most likely misplaced detection) cached as fp16
in the work folder under a hash of the demonstrations and the perception weights."""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.communication import TASK
from maniskill_tidy.models.decision import (
    HEADS_GOAL,
    HEADS_TASK,
    DecisionConfig,
    crop_goal,
    crop_layout,
    suspects,
)

FEATURES = ("sv", "sm", "fd", "fp")  # 256-d each, cached as fp16


SCALARS = ("mis", "det", "failed")


LABELS = HEADS_TASK + HEADS_GOAL
OFFSET = {"dx": 4, "dy": 4}  # -4..4 -> class 0..8


# ------------------------------------------------------------------- features of every row
@dataclass
class Rows:
    """Per-row tensors of one split, and the (episode, step, agent) -> row index."""

    x: dict[str, torch.Tensor]
    y: dict[str, torch.Tensor]
    index: torch.Tensor  # (E, T, N) row or -1
    hash: str

    @property
    def episodes(self) -> int:
        return self.index.shape[0]

    def __add__(self, other: Rows) -> Rows:
        """Both splits' rows as one (episodes of ``other`` after ours; same team size)."""
        if self.index.shape[-1] != other.index.shape[-1]:
            raise ValueError(f"rows of {self.index.shape[-1]} and {other.index.shape[-1]} agents")
        steps = max(self.index.shape[1], other.index.shape[1])
        n = len(next(iter(self.y.values())))

        def padded(index: torch.Tensor, offset: int) -> torch.Tensor:
            out = torch.full((index.shape[0], steps, index.shape[2]), -1, dtype=torch.long)
            out[:, : index.shape[1]] = torch.where(index >= 0, index + offset, -1)
            return out

        if set(self.x) != set(other.x):  # both come from one FEATURES_VERSION, so never expected
            raise ValueError(f"rows with inputs {sorted(self.x)} and {sorted(other.x)}")
        return Rows(
            {k: torch.cat([self.x[k], other.x[k]]) for k in self.x},
            {k: torch.cat([self.y[k], other.y[k]]) for k in self.y},
            torch.cat([padded(self.index, 0), padded(other.index, n)]),
            f"{self.hash}+{other.hash}",
        )

    def every(self, k: int) -> Rows:
        """The rows of every k-th step, one episode per phase (steps p, p + k, ... for p < k):
        what an agent that decides at a sub-goal step every k env steps sees
        (``DecisionConfig.decide_every``), each demonstration used once."""
        if k == 1:
            return self
        steps = -(-self.index.shape[1] // k)
        phases = []
        for p in range(k):
            part = self.index[:, p::k]
            out = torch.full((part.shape[0], steps, part.shape[2]), -1, dtype=torch.long)
            out[:, : part.shape[1]] = part
            phases.append(out)
        index = torch.stack(phases, dim=1).flatten(0, 1)  # episode e's phases side by side
        keep = (index >= 0).flatten(1).any(-1)  # a phase past an episode's end has no rows
        return Rows(self.x, self.y, index[keep], f"{self.hash}/every{k}")

    def batch(self, episodes: np.ndarray) -> tuple[list[dict], torch.Tensor, list[dict]]:
        """Agent-wise inputs and labels (B, T, ·) of some episodes, and ``present`` (B, T, N)."""
        idx = self.index[torch.as_tensor(episodes)]
        t = int((idx >= 0).any(-1).any(0).nonzero().max()) + 1
        idx = idx[:, :t]
        present = idx >= 0
        safe = idx.clamp(min=0)
        xs, ys = [], []
        for n in range(idx.shape[-1]):
            rows = safe[:, :, n]
            xs.append({k: v[rows].float() if v.is_floating_point() else v[rows]
                       for k, v in self.x.items()})  # fmt: skip
            ys.append({k: torch.where(present[:, :, n], v[rows], -1) for k, v in self.y.items()})
        for xn, yn in zip(xs, ys, strict=True):  # the sub-task a state message carries
            task = torch.stack([yn[k] for k in TASK], dim=-1)
            xn["prev_task"] = torch.cat([torch.full_like(task[:, :1], -1), task[:, :-1]], dim=1)
        return xs, present, ys


FEATURES_VERSION = 5  # 2: the crop's layout; 3: its goal channels (crop_goal); 4: the wide layout;


def _feature_hash(demos_hash: str, perception: Path) -> str:
    digest = hashlib.sha256(f"{FEATURES_VERSION}:{demos_hash}".encode())
    digest.update(hashlib.sha256((perception / "model.pt").read_bytes()).digest())
    return digest.hexdigest()[:16]


@torch.no_grad()
def embed_split(directory: Path, perception_dir: Path, cache: Path, progress: bool = True) -> Rows:
    """Run the frozen perception over every row of a demos folder (cached by hash)."""
    from maniskill_tidy.models.checkpoints import load_perception

    manifest = json.loads((directory / "manifest.json").read_text())
    key = _feature_hash(manifest["demos_hash"], perception_dir)
    path = cache / f"features_{key}.pt"
    if path.is_file():
        saved = torch.load(path, weights_only=False)
        saved["y"]["action"] = action_labels(directory)
        return Rows(saved["x"], saved["y"], saved["index"], key)
    perception = load_perception(perception_dir)
    k = perception.cfg.categories
    shards = sorted(directory.glob("house_*.npz"))
    parts: dict[str, list] = {}
    keys: list[tuple[int, int, int]] = []
    episodes = 0
    for shard in tqdm(shards, desc=f"features {directory.parent.name} {directory.name}",
                      unit="house", disable=not progress):  # fmt: skip
        with np.load(shard) as z:
            d = {name: z[name] for name in z.files}
        n = len(d["t"])
        g = perception.cfg.crop
        for start in range(0, n, 512):
            sl = slice(start, min(start + 512, n))
            rows = np.arange(sl.start, sl.stop)
            dets = np.flatnonzero(np.isin(d["det_row"], rows))
            crop = np.unpackbits(d["crop"][sl], axis=1)[:, : g * g * (k + 2)]
            f = perception.step_features(
                torch.from_numpy(d["rgb"][sl]),
                torch.from_numpy(d["seen"][sl].astype(np.float32)),
                torch.from_numpy(crop.reshape(-1, g, g, k + 2)),
                torch.from_numpy(d["det_row"][dets] - sl.start).long(),
                torch.from_numpy(d["det_type"][dets]).long(),
                torch.from_numpy(d["det_rest"][dets]).long(),
                torch.from_numpy(d["det_numeric"][dets]),
            )
            for name in FEATURES:
                parts.setdefault(name, []).append(f[name].half())
            for name in ("mis", "det"):
                parts.setdefault(name, []).append(f[name])
            suspect = suspects(torch.from_numpy(d["det_row"][dets] - sl.start),
                               torch.from_numpy(d["det_type"][dets]), f["p_detections"],
                               sl.stop - sl.start, len(load_catalog().pickupable))  # fmt: skip
            parts.setdefault("suspect", []).append(suspect.half())
            layout = crop_layout(crop.reshape(-1, g, g, k + 2))
            parts.setdefault("layout", []).append(torch.from_numpy(layout))
            goal = crop_goal(crop.reshape(-1, g, g, k + 2))
            parts.setdefault("goal", []).append(torch.from_numpy(goal))
            parts.setdefault("wide", []).append(torch.from_numpy(d["wide"][sl]))
        parts.setdefault("pose", []).append(torch.from_numpy(d["pose"]))
        for name in ("failed", "capability", "held", *LABELS):
            parts.setdefault(name, []).append(torch.from_numpy(d[name].astype(np.int64)))
        for e, t, a in zip(d["episode"], d["t"], d["agent"], strict=True):
            keys.append((episodes + int(e), int(t), int(a)))
        episodes += len(json.loads(str(d["episodes"])))
    cat = {name: torch.cat(v) for name, v in parts.items()}
    x = {name: cat[name]
         for name in (*FEATURES, "mis", "det", "suspect", "layout", "goal", "wide")}  # fmt: skip
    x["failed"] = cat["failed"].float()
    x["pose"] = cat["pose"].float()
    x["va"] = cat["capability"].float()
    x["held"] = cat["held"]
    y = {name: cat[name] + OFFSET.get(name, 0) for name in LABELS}
    agents = max(a for _, _, a in keys) + 1
    steps = max(t for _, t, _ in keys) + 1
    index = torch.full((episodes, steps, agents), -1, dtype=torch.long)
    e, t, a = (torch.tensor(c) for c in zip(*keys, strict=True))
    index[e, t, a] = torch.arange(len(keys))
    cache.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    torch.save({"x": x, "y": y, "index": index}, buf)
    write_atomic(path, buf.getvalue())
    y["action"] = action_labels(directory)
    return Rows(x, y, index, key)


def used_input(name: str, cfg: DecisionConfig) -> bool:
    """Whether a model with ``cfg`` reads the cached input ``name`` (the goal channels are
    340 MB per 63k rows)."""
    return {"layout": cfg.layout, "goal": cfg.goal_map, "wide": cfg.wide_layout,
            "suspect": cfg.suspects}.get(name, True)  # fmt: skip


def action_labels(directory: Path) -> torch.Tensor:
    """The teacher's low-level action of every row of a demos folder, in the rows' order
    (w/o HierDec.'s labels; read from the shards, a few kB each)."""
    parts = []
    for shard in sorted(directory.glob("house_*.npz")):
        with np.load(shard) as z:
            parts.append(torch.from_numpy(z["action"].astype(np.int64)))
    return torch.cat(parts)
