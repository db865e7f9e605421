"""Training the pixels track's segmenter on the project's own renders.

``maniskill-tidy train-segmenter --data data/segmenter/HeteroTidy-v2 --out agents/segmenter-v2``
reads the frames ``segmenter-data`` rendered (train houses train, val houses select, test houses
report once), fits ``models/segmenter.py`` with class-weighted cross-entropy on random crops at
full resolution, keeps the epoch of best val mask AP50 over the pickupable types (then pixel
accuracy), and writes
``model.pt`` (fp16), ``card.json`` (val curve, test mask AP by size, training time, data hashes,
weights sha256) and ``curve.png`` beside it, then the int8 graph agents run (``quantize``), through
which the card's val and test are scored. Resumes from its last epoch (an atomic checkpoint).
``--init`` starts a run from a trained segmenter's weights: the shipped v2 segmenter is three
runs of 16 epochs, each from the last (``make train-segmenter``).
"""

from __future__ import annotations

import copy
import io
import json
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional as F
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.mask_ap import mask_ap, score_threshold
from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import (
    INT8_CALIBRATION,
    Runtime,
    Segmenter,
    int8_graph,
    predict,
    upsample,
)
from maniskill_tidy.perception.instances import (
    Mask2D,
    coarse,
    refined,
    scored_by_relief,
    split_instances,
)
from maniskill_tidy.perception.seg_classes import seg_classes

SPLITS = ("train", "val", "test")


@dataclass
class SegTrainConfig:
    data: str  # segmenter-data's folder: train/, val/, test/
    out: str  # where model.pt and card.json go
    # about 110-160 s each on 2 cores for 13k frames; 40 from scratch did no better on val for
    # the 12, 16 one, but the 24, 32 one gained from 16 more twice (init: val AP50 0.449,
    # 0.483, 0.504)
    epochs: int = 16
    batch: int = 16
    crop: int = 128  # px: training crops at full resolution (frames are 224)
    lr: float = 2e-3
    # models/segmenter.py; 24 and 32 channels at strides 2 and 4 (the label head reads the
    # stride-2 level): v2 val mask AP50 0.436 against 0.389 for 16 and 24 (and 0.308 against
    # 0.265 for 16, 24 against 12, 16 under earlier scoring); 1.6x the cost in fp32, the same
    # as 16, 24 in fp32 once served in int8 (research log)
    widths: tuple[int, ...] = (24, 32, 32, 48, 64)
    stem: int = 0  # channels of a full-resolution convolution first (0: none; 8: +0.6 ms)
    head: int = 0  # channels of a hidden 1 x 1 layer before the class logits (0: none)
    seed: int = 0
    eval_frames: int = 400  # val frames scored per epoch (evenly spaced); test: all
    weight_power: float = 0.75  # class weights: 1 / frequency ** this (val: 0.25-1 tried)
    # share of crops around a pickupable object: they cover ~1 % of the pixels, and random
    # crops of an epoch showed them too rarely to learn their types (val AP50 0 after 2 epochs)
    focus: float = 0.5
    # weight of a soft Dice loss on "is this pixel a pickupable object" (the summed
    # probability of the pickupable types) beside the cross-entropy: the segmenter's misses
    # are which pixels are objects more than their type (research log); 0: none
    objectness: float = 0.0
    zoom: float = 1.0  # half the crops blown up by up to this factor (1: none)
    relief: bool = False  # the depth's local relief as input channels (models/segmenter.py)
    # a trained segmenter's folder whose weights start this run (its architecture, which the
    # run's must match): more epochs for a run whose loss still fell at its end
    init: str | None = None
    # more train frames: segmenter-data folders rendered from other houses (a dataset generated
    # with another seed, so none of them is a val or test house of ``data``), joined to its
    # train split; the card names them by data hash
    extra: tuple[str, ...] = ()
    limit: dict = field(default_factory=dict)  # split -> at most this many frames (tests)


FRAME_KEYS = ("rgb", "depth_mm", "cls", "instance")
TRAIN_KEYS = ("rgb", "depth_mm", "cls")  # training reads no instances: a quarter less memory


def load_split(folder: Path | list[Path], limit: int | None = None,
               keys: tuple[str, ...] = FRAME_KEYS) -> dict[str, np.ndarray]:  # fmt: skip
    """Every frame of a split's shards (of several folders, one after the other), in house
    order; ``limit``: evenly spaced frames."""
    folders = folder if isinstance(folder, list) else [folder]
    per_folder = {f: sorted(Path(f).glob("house_*.npz")) for f in folders}
    if missing := [f for f, found in per_folder.items() if not found]:
        raise FileNotFoundError(f"{missing[0]}: no house_*.npz; render it with `maniskill-tidy "
                                "segmenter-data`")  # fmt: skip
    shards = [s for found in per_folder.values() for s in found]
    parts: dict[str, list] = {k: [] for k in keys}
    for shard in shards:
        with np.load(shard) as z:
            for k in parts:
                parts[k].append(z[k])
    out = {}
    for k in keys:  # one key at a time: the shards' copies go as each array is made
        out[k] = np.concatenate(parts.pop(k))
    if limit is not None and limit < len(out["rgb"]):
        keep = np.linspace(0, len(out["rgb"]) - 1, limit).round().astype(int)
        out = {k: v[keep] for k, v in out.items()}
    return out


def class_weights(cls: np.ndarray, n: int, power: float) -> torch.Tensor:
    """1 / frequency ** ``power`` per class, seen at the loss's resolution, averaging 1 over
    the pixels: pickupable objects cover a tiny share of the pixels and matter most."""
    counts = np.bincount(cls[:, ::2, ::2].ravel(), minlength=n).astype(np.float64)
    w = np.where(counts > 0, 1.0 / np.maximum(counts, 1) ** power, 0.0)
    w *= counts.sum() / max((w * counts).sum(), 1e-12)
    return torch.tensor(w, dtype=torch.float32)


def objectness_dice(logits: torch.Tensor, target: torch.Tensor, first: int) -> torch.Tensor:
    """1 - soft Dice of the pickupable-object pixels over a batch (classes ``first`` on):
    measured on overlap, not per pixel, so the ~1 % of pixels that are objects weigh as much
    as the rest."""
    p = logits.softmax(1)[:, first:].sum(1)
    t = (target >= first).float()
    return 1.0 - (2.0 * (p * t).sum() + 1.0) / (p.sum() + t.sum() + 1.0)


def _tensors(frames: dict, index: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    rgb = torch.from_numpy(frames["rgb"][index]).permute(0, 3, 1, 2).float()
    depth = torch.from_numpy(frames["depth_mm"][index].astype(np.float32) / 1000.0)[:, None]
    return rgb, depth


def truth_masks(cls: np.ndarray, instance: np.ndarray, pickupable: list[int]) -> list[Mask2D]:
    out = []
    for i in np.unique(instance[instance > 0]):
        m = instance == i
        c = int(cls[m][0])
        if c in pickupable:
            out.append(Mask2D(c, m, 1.0))
    return out


def instance_pairs(
    model: Segmenter | Runtime, frames: dict, relabel=None
) -> tuple[list, list[int], np.ndarray]:
    """Per frame (truth, predicted instances) over the pickupable types, the instances made as
    agents make them (on the network's grid, then refined to the frames' resolution with
    depth's guidance, ``instances.refined``; masks of ``MIN_PIXELS`` or more: agents cannot
    act on smaller ones) and compared at the frames' resolution;
    the pickupable classes and the predicted labels, upsampled. ``relabel(labels, probs,
    depth)``: a change to a frame's labels on the grid before its instances are made (probes)."""
    classes = seg_classes()
    pickupable = [i for i in range(len(classes.names)) if classes.is_pickupable(i)]
    depth = frames["depth_mm"].astype(np.float32) / 1000.0
    if isinstance(model, Runtime):  # the served graph, as agents run it
        labels, probs = model.predict(frames["rgb"], depth)
    else:
        labels, probs = predict(model, frames["rgb"], depth)
    step = depth.shape[1] // labels.shape[1]
    least = -(-MIN_PIXELS // step**2)
    pairs = []
    for k in range(len(labels)):
        grid = coarse(depth[k], step)
        lab = labels[k] if relabel is None else relabel(labels[k], probs[k], grid)
        masks = scored_by_relief(split_instances(lab, grid, pickupable, probs[k], least),
                                 grid, pickupable)  # fmt: skip
        truth = truth_masks(frames["cls"][k], frames["instance"][k], pickupable)
        pairs.append((truth, refined(masks, depth[k], step, MIN_PIXELS)))
    return pairs, pickupable, upsample(labels, probs, depth.shape[1:3])[0]


def agent_threshold(model: Segmenter | Runtime, frames: dict) -> dict:
    """The confidence under which agents leave an object mask out: the best F1 on val frames
    (``mask_ap.score_threshold``), with its precision and recall."""
    pairs, pickupable, labels = instance_pairs(model, frames)
    return score_threshold(pairs, pickupable, labels.shape[1:3], ignore_below=MIN_PIXELS)


def evaluate(model: Segmenter | Runtime, frames: dict) -> dict:
    """Mask AP over the pickupable types (instances from the predicted labels and depth) of
    the objects an agent could act on (``MIN_PIXELS`` or more: the env's visibility; smaller
    ones ignored, also reported counted), and the share of pickupable pixels labelled with
    their type."""
    classes = seg_classes()
    pairs, pickupable, labels = instance_pairs(model, frames)
    out = mask_ap(pairs, pickupable, labels.shape[1:3], ignore_below=MIN_PIXELS)
    every = mask_ap(pairs, pickupable, labels.shape[1:3])  # tinier objects counted too
    out["AP50_every_size"], out["AP_every_size"] = every["AP50"], every["AP"]
    on_objects = classes.is_pickupable(frames["cls"]) & (frames["cls"] > 0)
    out["pixel_accuracy_pickupable"] = round(
        float((labels[on_objects] == frames["cls"][on_objects]).mean()), 4
    ) if on_objects.any() else None  # fmt: skip
    out["pixel_accuracy"] = round(float((labels == frames["cls"]).mean()), 4)
    return out


def _crops(frames: dict, index: np.ndarray, crop: int, rng: np.random.Generator,
           focus: float = 0.0, zoom: float = 1.0):  # fmt: skip
    """Random crops (the same place per frame for all of its images) and horizontal flips;
    a ``focus`` share of them holds a pickupable object's pixel (where the frame has one).
    ``zoom`` > 1: half the crops are a smaller square blown up by up to that factor, their
    depth divided by it (as if the camera stood that much nearer): small objects seen large."""
    rgb, depth = _tensors(frames, index)
    labels = frames["cls"][index]
    cls = torch.from_numpy(labels.astype(np.int64))
    h, w = cls.shape[1:]
    if zoom > 1:
        scale = np.where(rng.random(len(index)) < 0.5, rng.uniform(1.0, zoom, len(index)), 1.0)
        sizes = np.maximum(np.round(crop / scale / 2).astype(int) * 2, 2)  # even, as labels
        ys = (rng.random(len(index)) * (h - sizes + 1)).astype(int)
        xs = (rng.random(len(index)) * (w - sizes + 1)).astype(int)
    else:  # the random draws of the shipped segmenters' training, unchanged
        sizes = np.full(len(index), crop)
        ys = rng.integers(0, h - crop + 1, len(index))
        xs = rng.integers(0, w - crop + 1, len(index))
    classes = seg_classes()
    for i in np.nonzero(rng.random(len(index)) < focus)[0]:
        rows, cols = np.nonzero(classes.is_pickupable(labels[i]) & (labels[i] > 0))
        if len(rows):  # a crop around one of them, anywhere in the crop
            k = rng.integers(len(rows))
            ys[i] = np.clip(rows[k] - rng.integers(sizes[i]), 0, h - sizes[i])
            xs[i] = np.clip(cols[k] - rng.integers(sizes[i]), 0, w - sizes[i])
    ys, xs = ys // 2 * 2, xs // 2 * 2  # even: labels at half resolution
    flips = rng.random(len(index)) < 0.5
    out = [], [], []
    for i, (y, x, c) in enumerate(zip(ys, xs, sizes, strict=True)):
        if c == crop:
            parts = (rgb[i, :, y : y + c, x : x + c], depth[i, :, y : y + c, x : x + c],
                     cls[i, y : y + c : 2, x : x + c : 2])  # fmt: skip
        else:  # blown up: images bilinear, labels nearest, depth nearer by the same factor
            parts = (
                F.interpolate(rgb[i : i + 1, :, y : y + c, x : x + c], size=(crop, crop),
                              mode="bilinear", align_corners=False)[0],
                F.interpolate(depth[i : i + 1, :, y : y + c, x : x + c], size=(crop, crop),
                              mode="nearest")[0] * (c / crop),
                F.interpolate(cls[None, None, i, y : y + c, x : x + c].float(),
                              size=(crop // 2, crop // 2), mode="nearest")[0, 0].long(),
            )  # fmt: skip
        if flips[i]:
            parts = tuple(p.flip(-1) for p in parts)
        for store, p in zip(out, parts, strict=True):
            store.append(p)
    return tuple(torch.stack(s) for s in out)


def _start(cfg: SegTrainConfig, model: Segmenter) -> dict:
    """Load ``cfg.init``'s weights into ``model``; what the card says of them."""
    init, card = checkpoints.load_segmenter(Path(cfg.init))
    theirs = card.get("config", {})
    ours = {"widths": list(cfg.widths), "stem": cfg.stem, "head": cfg.head, "relief": cfg.relief}
    if any(theirs.get(k, v) != v for k, v in ours.items()):
        raise ValueError(f"--init {cfg.init}: trained with " + ", ".join(
            f"{k} {theirs.get(k)}" for k in ours) + "; expected this run's " + ", ".join(
            f"{k} {v}" for k, v in ours.items()))  # fmt: skip
    model.load_state_dict(init.state_dict())
    return {"from": card.get("name", Path(cfg.init).name), "weights_sha256":
            checkpoints.weights_sha256(Path(cfg.init)), "epochs": theirs.get("epochs"),
            "train_seconds": card.get("train_seconds")}  # fmt: skip


def _extra_manifest(folder: Path, train: dict) -> dict:
    """The manifest of ``--extra`` frames, checked against the train split's: the same look
    and classes, other houses."""
    if not (folder / "manifest.json").is_file():
        raise FileNotFoundError(f"--extra {folder}: no segmenter frames (manifest.json); "
                                "render them with `maniskill-tidy segmenter-data`")  # fmt: skip
    m = json.loads((folder / "manifest.json").read_text())
    if m["classes"] != train["classes"] or m["env"] != train["env"]:
        raise ValueError(f"--extra {folder}: rendered in {m['env']} with classes {m['classes']}; "
                         f"expected {train['env']} with {train['classes']}")  # fmt: skip
    if m["dataset_hash"] == train["dataset_hash"]:
        raise ValueError(f"--extra {folder}: rendered from the train split's dataset; expected "
                         "the houses of a dataset generated with another seed")  # fmt: skip
    return m


def _rank(scores: dict) -> tuple[float, float]:
    """How val ranks epochs: mask AP50, then pixel accuracy (a segmenter that finds no object
    yet still learns the floor and walls teams map with)."""
    return (scores["AP50"], scores["pixel_accuracy"])


def train_segmenter(cfg: SegTrainConfig, progress: bool = True) -> dict:
    data, out = Path(cfg.data), Path(cfg.out)
    classes = seg_classes()
    for s in SPLITS:
        if not (data / s / "manifest.json").is_file():
            raise FileNotFoundError(f"{data / s}: no segmenter frames (manifest.json); render "
                                    "them with `maniskill-tidy segmenter-data`")  # fmt: skip
    manifests = {s: json.loads((data / s / "manifest.json").read_text()) for s in SPLITS}
    for s, m in manifests.items():
        if m["classes"] != classes.digest:
            raise ValueError(f"{data / s}: rendered with another class table ({m['classes']}, "
                             f"this code's is {classes.digest}); render it again")  # fmt: skip
    extras = {e: _extra_manifest(Path(e), manifests["train"]) for e in cfg.extra}
    looks = {m["env"] for m in [*manifests.values(), *extras.values()]}
    if len(looks) != 1:
        raise ValueError(f"{data}: splits rendered in different looks {sorted(looks)}")
    train = load_split([data / "train", *map(Path, cfg.extra)], cfg.limit.get("train"),
                       TRAIN_KEYS)  # fmt: skip
    val = load_split(data / "val", cfg.limit.get("val", cfg.eval_frames))
    torch.manual_seed(cfg.seed)
    model = Segmenter(len(classes.names), cfg.widths, cfg.stem, cfg.head, cfg.relief)
    start = _start(cfg, model) if cfg.init else None
    optimiser = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=1e-4)
    steps = cfg.epochs * max(1, len(train["rgb"]) // cfg.batch)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, cfg.lr, total_steps=steps)
    weights = class_weights(train["cls"], len(classes.names), cfg.weight_power)
    key = {**asdict(cfg), "widths": list(cfg.widths), "classes": classes.digest,
           "data": {s: m["data_hash"] for s, m in manifests.items()}}  # fmt: skip
    key["extra"] = [{"data_hash": m["data_hash"], "dataset_hash": m["dataset_hash"],
                     "frames": m["frames"]} for m in extras.values()]  # fmt: skip
    if not key["extra"]:  # the key of runs from before the option, whose checkpoints resume
        key.pop("extra")
    key.pop("out")
    if start:  # the weights it starts from, not where they lay
        key["init"] = start["weights_sha256"]
    ckpt = out / "checkpoint.pt"
    state = {"epoch": 0, "seconds": 0.0, "curve": [], "best": None, "best_epoch": 0}
    best_state = copy.deepcopy(model.state_dict())
    rng = np.random.default_rng(cfg.seed)
    if ckpt.is_file():
        saved = torch.load(ckpt, weights_only=False)
        if saved["key"] != key:
            raise ValueError(f"{ckpt}: a checkpoint of another configuration; remove it or "
                             "pass another --out")  # fmt: skip
        model.load_state_dict(saved["model"])
        optimiser.load_state_dict(saved["optimiser"])
        schedule.load_state_dict(saved["schedule"])
        state, best_state = saved["state"], saved["best_state"]
        torch.set_rng_state(saved["torch_rng"])
        rng.bit_generator.state = saved["rng"]
    out.mkdir(parents=True, exist_ok=True)
    bar = tqdm(total=cfg.epochs, initial=state["epoch"], unit="epoch", disable=not progress,
               desc=f"segmenter {looks.pop()}")  # fmt: skip
    with bar:
        while state["epoch"] < cfg.epochs:
            started = time.perf_counter()
            model.train()
            order = rng.permutation(len(train["rgb"]))
            losses = []
            for s in range(0, len(order) - cfg.batch + 1, cfg.batch):
                rgb, depth, target = _crops(train, order[s : s + cfg.batch], cfg.crop, rng,
                                            cfg.focus, cfg.zoom)  # fmt: skip
                logits = model(rgb, depth)
                loss = F.cross_entropy(logits, target, weight=weights)
                if cfg.objectness:
                    loss = loss + cfg.objectness * objectness_dice(
                        logits, target, classes.first_pickupable
                    )
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                schedule.step()
                losses.append(loss.item())
            model.eval()
            v = evaluate(model, val)
            state["epoch"] += 1
            state["seconds"] += time.perf_counter() - started
            point = {"epoch": state["epoch"], "train_loss": float(np.mean(losses))}
            for k in ("AP", "AP50", "pixel_accuracy_pickupable"):
                point[f"val_{k}"] = v[k]
            state["curve"].append(point)
            if state["best"] is None or _rank(v) > _rank(state["best"]):
                state["best"], state["best_epoch"] = v, state["epoch"]
                best_state = copy.deepcopy(model.state_dict())
            buf = io.BytesIO()
            torch.save({"key": key, "model": model.state_dict(),
                        "optimiser": optimiser.state_dict(), "schedule": schedule.state_dict(),
                        "torch_rng": torch.get_rng_state(),
                        "rng": rng.bit_generator.state, "state": state,
                        "best_state": best_state}, buf)  # fmt: skip
            write_atomic(ckpt, buf.getvalue())
            bar.update(1)
            bar.set_postfix(val_AP50=f"{v['AP50']:.3f}")
    model.load_state_dict(best_state)
    # an earlier run's card names other weights' sha256: loading these would be refused
    (out / "card.json").unlink(missing_ok=True)
    checkpoints.save_segmenter(model, out)
    model = checkpoints.load_segmenter(out)[0]  # scored as it ships: fp16-rounded weights
    test = load_split(data / "test", cfg.limit.get("test"))
    card = {
        "name": out.name,
        "look": manifests["train"]["env"],
        "approximation": "a small U-Net trained from scratch on our renders stands in for the "
        "paper's Mask R-CNN; instances are connected components split at depth jumps",
        "config": key,
        "classes": list(classes.names),
        "parameters": sum(p.numel() for p in model.parameters()),
        "frames": {"train": len(train["rgb"]), "val": len(val["rgb"]), "test": len(test["rgb"])},
        "best_epoch": state["best_epoch"],
        **({"init": start} if start else {}),
        "curve": state["curve"],
        "train_seconds": round(state["seconds"], 1),
        "weights_sha256": checkpoints.weights_sha256(out),
    }
    # val and test (reported once, for the epoch val chose) and the agents' threshold (chosen
    # on val) of the int8 graph agents run; the curve's are the fp32 weights'
    card = quantize(out, data, val, test, card)
    plot_curve(card, out / "curve.png")
    ckpt.unlink(missing_ok=True)
    return card


def _frames(card: dict, data: Path) -> tuple[dict, dict, dict | None]:
    """The val and test frames a card was scored on, and where they are not its bytes, their
    hashes (for the card's ``scored_on``, which :func:`_score` writes). Frames made again on
    another machine (same look, classes and number of frames, other bytes: frames are the
    same bytes on one machine, not on every one) are read with a warning; other frames are
    refused."""
    manifests = {s: json.loads((data / s / "manifest.json").read_text())
                 for s in ("val", "test")}  # fmt: skip
    differ = [s for s in manifests if manifests[s]["data_hash"] != card["config"]["data"][s]]
    scored_on = None
    if differ:
        same_protocol = (
            all(
                manifests[s].get("env") == card["look"]
                and manifests[s].get("classes") == card["config"]["classes"]
                and manifests[s].get("frames", -1) >= card["frames"][s]
                for s in manifests
            )
            and manifests["test"]["frames"] == card["frames"]["test"]
        )
        if not same_protocol:
            raise ValueError(f"{data}: not the frames the card was trained and scored on (data "
                             "hashes differ)")  # fmt: skip
        print(f"warning: {data}: the {' and '.join(differ)} frames have the card's look, "
              "classes and number but other bytes (made on another machine?): scored on "
              "them, their hashes kept as the card's scored_on", file=sys.stderr)  # fmt: skip
        scored_on = {s: manifests[s]["data_hash"] for s in manifests}
    cfg = card["config"]
    val = load_split(data / "val", cfg["limit"].get("val", cfg["eval_frames"]))
    return val, load_split(data / "test", cfg["limit"].get("test")), scored_on


def _keep_scores(card: dict) -> dict:
    """``card`` with its current scores appended to ``scored_before``, before a rescoring."""
    scores = {k: card[k] for k in ("val", "test", "agent_threshold", "scored_on") if k in card}
    card["scored_before"] = [*card.get("scored_before", []), scores]
    return card


def _score(folder: Path, card: dict, val: dict, test: dict, scored_on: dict | None) -> None:
    """The card's ``val``, ``test`` and ``agent_threshold`` of what agents run: the int8 graph
    when the card names one (the fp16 weights' own under ``int8.fp16_torch``), else the fp16
    weights; ``scored_on``: the frames' hashes where they are not those it was trained on."""
    card.pop("scored_on", None)
    if scored_on:
        card["scored_on"] = scored_on
    model = checkpoints.load_segmenter(folder)[0]
    if card.get("int8"):
        card["int8"]["fp16_torch"] = {"val": evaluate(model, val), "test": evaluate(model, test)}
        model = Runtime((folder / checkpoints.INT8).read_bytes(), torch.get_num_threads())
    card["val"], card["test"] = evaluate(model, val), evaluate(model, test)
    card["agent_threshold"] = agent_threshold(model, val)


def quantize(folder: str | Path, data: str | Path, val: dict | None = None,
             test: dict | None = None, card: dict | None = None) -> dict:  # fmt: skip
    """Write the int8 graph agents run (``model.int8.onnx``, calibrated on
    ``INT8_CALIBRATION`` evenly spaced val frames) beside a trained segmenter, and score its
    card through it (``card``: a new one, else the folder's, whose scores stay under
    ``scored_before``)."""
    import onnxruntime

    folder, data = Path(folder), Path(data)
    if card is None:
        if not (folder / "card.json").is_file():
            raise FileNotFoundError(f"{folder / 'card.json'} not found: expected a segmenter "
                                    "trained by `maniskill-tidy train-segmenter`")  # fmt: skip
        card = _keep_scores(json.loads((folder / "card.json").read_text()))
    scored_on = None
    if val is None or test is None:
        val, test, scored_on = _frames(card, data)
    model = checkpoints.load_segmenter(folder)[0]
    calibration = load_split(data / "val", INT8_CALIBRATION)
    graph = int8_graph(model, calibration["rgb"], calibration["depth_mm"] / np.float32(1000.0))
    card["int8"] = {
        "file": checkpoints.INT8,
        "sha256": checkpoints.save_segmenter_int8(folder, graph),
        "calibration": f"{len(calibration['rgb'])} evenly spaced val frames; ONNX Runtime "
        f"{onnxruntime.__version__} static QDQ, per-channel int8 weights, uint8 activations, "
        "MinMax; the first convolution and the label head in fp32",
    }
    _score(folder, card, val, test, scored_on)
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    return card


def rescore(folder: str | Path, data: str | Path) -> dict:
    """A trained segmenter's card scored again with this code's instances (its weights, int8
    graph, val frames and test frames unchanged): ``val``, ``test`` and ``agent_threshold``
    replaced, the previous ones kept under ``scored_before``. For a card whose scoring changed
    after training (how agents make instances); its learning curve stays as measured then."""
    folder, data = Path(folder), Path(data)
    card = _keep_scores(json.loads((folder / "card.json").read_text()))
    val, test, scored_on = _frames(card, data)
    _score(folder, card, val, test, scored_on)
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    return card


def plot_curve(card: dict, out: Path) -> Path:
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    curve = card["curve"]
    epochs = [c["epoch"] for c in curve]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3))
    a.plot(epochs, [c["train_loss"] for c in curve])
    a.set(xlabel="epoch", ylabel="weighted cross-entropy", title="train loss")
    b.plot(epochs, [c["val_AP50"] for c in curve], label="mask AP50")
    b.plot(epochs, [c["val_AP"] for c in curve], label="mask AP")
    b.axvline(card["best_epoch"], color="grey", ls=":")
    b.set(xlabel="epoch", title="val: pickupable types")
    b.legend()
    fig.suptitle(f"{card['name']} ({card['look']})")
    return save_figure(fig, out, dpi=100)
