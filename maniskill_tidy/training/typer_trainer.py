"""Training the object typer (``models/object_typer.py``) on the segmenter's frames.

Samples are made as agents make their masks: on each frame of ``segmenter-data``, the parts of
what the floor plan does not explain (``perception/object_space.py``), with the shipped
segmenter's labels and margins as agents get them (its int8 graph), each labelled with the type
of the renderer's object it covers at IoU 0.5, else "not an object". Train houses train, val
houses select the epoch; test frames are scored once, by ``floor_plan_masks.py``.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from maniskill_tidy.common.files import file_sha256, sha256, write_atomic
from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.models.checkpoints import served_segmenter, served_sha256
from maniskill_tidy.models.object_typer import ObjectTyper, type_index
from maniskill_tidy.perception.instances import split_instances
from maniskill_tidy.perception.object_crops import crop_inputs
from maniskill_tidy.perception.object_space import ObjectSpace, unexplained
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.tasks.dataset import load_dataset
from maniskill_tidy.training.segmenter_trainer import truth_masks

IOU = 0.5


def samples(frames: Path, dataset: Path, split: str, segmenter: Path, every: int = 1) -> dict:
    """Every part of every ``every``-th frame of ``frames/<split>``: crops, numbers, target
    (type index, or T for "not an object") and the part's pixels."""
    runtime, seg_sha, _ = served_segmenter(segmenter, torch.get_num_threads())
    houses = load_dataset(dataset, split).houses
    index, labels = type_index()
    names = [seg_classes().names[i] for i in labels]
    pickupable = [int(i) for i in np.nonzero(index >= 0)[0]]
    out: dict[str, list] = {"crops": [], "numbers": [], "target": [], "pixels": []}
    shards = sorted((frames / split).glob("house_*.npz"))
    for shard in tqdm(shards, desc=f"typer samples {split}", unit="house"):
        space = ObjectSpace(houses[shard.stem])
        with np.load(shard) as z:
            keep = np.arange(0, len(z["rgb"]), every)
            f = {k: z[k][keep] for k in ("rgb", "depth_mm", "cls", "instance", "intrinsics",
                                         "extrinsics")}  # fmt: skip
        depth = f["depth_mm"].astype(np.float32) / 1000
        labels, margins = [], []
        for s in range(0, len(keep), 32):
            lab, mar = runtime(f["rgb"][s : s + 32], depth[s : s + 32])
            labels.append(lab)
            margins.append(mar)
        labels, margins = np.concatenate(labels), np.concatenate(margins)
        for j in range(len(keep)):
            d = depth[j]
            free = unexplained(space, d, f["intrinsics"][j], f["extrinsics"][j])
            parts = split_instances(free.astype(np.uint8), d, [1], None, MIN_PIXELS)
            if not parts:
                continue
            truth = truth_masks(f["cls"][j], f["instance"][j], pickupable)
            for p in parts:
                target = len(names)
                for t in truth:
                    inter = (p.mask & t.mask).sum()
                    if inter and inter / (p.mask | t.mask).sum() >= IOU:
                        target = int(index[t.cls])
                out["target"].append(target)
                out["pixels"].append(p.area)
            crops, numbers = crop_inputs(parts, f["rgb"][j], d, float(f["intrinsics"][j][0, 0]),
                                         labels[j], margins[j], index)  # fmt: skip
            out["crops"].append(crops.astype(np.float16))
            out["numbers"].append(numbers)
    result = {"crops": np.concatenate(out["crops"]), "numbers": np.concatenate(out["numbers"]),
              "target": np.array(out["target"], np.int64),
              "pixels": np.array(out["pixels"], np.int64)}  # fmt: skip
    manifest = json.loads((frames / split / "manifest.json").read_text())
    result["meta"] = {"frames_hash": manifest["data_hash"], "segmenter": seg_sha, "every": every,
                      "types": names}  # fmt: skip
    return result


def cached_samples(frames: Path, dataset: Path, split: str, segmenter: Path, work: Path,
                   every: int = 1) -> dict:  # fmt: skip
    """:func:`samples`, kept in ``work`` and made again when their frames or segmenter differ."""
    path = work / f"{split}.npz"
    manifest = json.loads((frames / split / "manifest.json").read_text())
    want = {"frames_hash": manifest["data_hash"], "segmenter": served_sha256(segmenter),
            "every": every}  # fmt: skip
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if all(meta.get(k) == v for k, v in want.items()):
                return {k: z[k] for k in ("crops", "numbers", "target", "pixels")} | {"meta": meta}
    s = samples(frames, dataset, split, segmenter, every)
    work.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **{k: v for k, v in s.items() if k != "meta"}, meta=json.dumps(s["meta"]))
    tmp.replace(path)
    return s


@dataclass
class TyperConfig:
    frames: str = "data/segmenter/HeteroTidy-v2"
    dataset: str = "data/tidy120"
    segmenter: str = "agents/segmenter-v2"
    out: str = "agents/experiments/typer-v2"
    work: str = "data/typer/HeteroTidy-v2"
    epochs: int = 20
    batch: int = 256
    lr: float = 2e-3
    width: int = 32
    seed: int = 0
    every: int = 1


def accuracy(model: ObjectTyper, s: dict) -> dict:
    """Top-1 accuracy over the parts that are objects, over all parts, and the share of
    non-objects called objects."""
    pred = predict(model, s["crops"], s["numbers"]).argmax(1)
    t = s["target"]
    objects = t < model.types
    return {"objects": round(float((pred[objects] == t[objects]).mean()), 4),
            "all": round(float((pred == t).mean()), 4),
            "false_objects": round(float((pred[~objects] < model.types).mean()), 4),
            "object_parts": int(objects.sum()), "parts": int(len(t))}  # fmt: skip


def predict(model: ObjectTyper, crops: np.ndarray, numbers: np.ndarray,
            batch: int = 1024) -> np.ndarray:  # fmt: skip
    """Softmax probabilities (N, types + 1)."""
    model.eval()
    out = []
    with torch.inference_mode():
        for s in range(0, len(crops), batch):
            c = torch.from_numpy(np.asarray(crops[s : s + batch], np.float32))
            n = torch.from_numpy(np.asarray(numbers[s : s + batch], np.float32))
            out.append(torch.softmax(model(c, n), 1).numpy())
    return np.concatenate(out) if out else np.zeros((0, model.types + 1), np.float32)


def train_typer(cfg: TyperConfig) -> dict:
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    frames, dataset, seg = Path(cfg.frames), Path(cfg.dataset), Path(cfg.segmenter)
    train = cached_samples(frames, dataset, "train", seg, Path(cfg.work), cfg.every)
    val = cached_samples(frames, dataset, "val", seg, Path(cfg.work), cfg.every)
    types = len(train["meta"]["types"])
    model = ObjectTyper(types, train["numbers"].shape[1], cfg.width)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=1e-4)
    steps = cfg.epochs * (-(-len(train["target"]) // cfg.batch))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, cfg.lr, total_steps=steps)
    loss_fn = nn.CrossEntropyLoss()
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    curve, best, start = [], None, time.perf_counter()
    for epoch in range(1, cfg.epochs + 1):
        model.train()
        order = rng.permutation(len(train["target"]))
        total = 0.0
        for s in tqdm(range(0, len(order), cfg.batch), desc=f"typer epoch {epoch}", leave=False):
            i = np.sort(order[s : s + cfg.batch])
            c = torch.from_numpy(train["crops"][i].astype(np.float32))
            if rng.random() < 0.5:  # a mirrored object is the same type
                c = c.flip(3)
            n = torch.from_numpy(train["numbers"][i])
            loss = loss_fn(model(c, n), torch.from_numpy(train["target"][i]))
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss) * len(i)
        score = accuracy(model, val)
        curve.append({"epoch": epoch, "train_loss": round(total / len(order), 4), "val": score})
        print(f"epoch {epoch}: loss {total / len(order):.4f} val {score}", flush=True)
        if best is None or score["all"] > best["val"]["all"]:
            best = {"epoch": epoch, "val": score}
            torch.save({"config": model.config(), "state": model.state_dict()}, out / "typer.tmp")
            (out / "typer.tmp").replace(out / "typer.pt")
    card = {
        "name": out.name, "config": asdict(cfg), "model": model.config(),
        "parameters": sum(p.numel() for p in model.parameters()),
        "samples": {"train": int(len(train["target"])), "val": int(len(val["target"]))},
        "data": {"train": train["meta"], "val": val["meta"] | {"types": None}},
        "best": best, "curve": curve, "train_seconds": round(time.perf_counter() - start, 1),
        "weights_sha256": file_sha256(out / "typer.pt"),
        "approximation": "a 4-layer CNN on 32 px crops stands in for Mask R-CNN's box head",
    }  # fmt: skip
    write_atomic(out / "card.json", json.dumps(card, indent=1).encode())
    return card


def load_typer(folder: Path) -> ObjectTyper:
    ckpt = torch.load(Path(folder) / "typer.pt", weights_only=True)
    model = ObjectTyper(**ckpt["config"])
    model.load_state_dict(ckpt["state"])
    return model.eval()


__all__ = ["TyperConfig", "train_typer", "load_typer", "samples", "sha256"]
