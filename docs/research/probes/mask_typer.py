"""A second stage that names each object mask's type, as Mask R-CNN's box head names a proposal:
a small CNN on a crop of the frame around the mask (RGB, the mask, depth relative to the
mask's), with the mask's metric size, its height and the segmenter's votes beside it, trained on
the masks agents make on *train*-house frames, each labelled with the type of the object it
covers (at least half of its pixels on it), or "none". With the floor plan's extents, a perfect
typer lifts val mask AP50 from 0.485 to 0.654 (``floor_plan_masks.py --true-type``); this asks
how much of that a learned one recovers (``floor_plan_masks.py --typer out/typer``).

    .venv/bin/python docs/research/probes/mask_typer.py crops agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/train --dataset data/tidy120 --out out/typer
    .venv/bin/python docs/research/probes/mask_typer.py crops agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --dataset data/tidy120 --split val --per 20 \\
        --out out/typer
    .venv/bin/python docs/research/probes/mask_typer.py train --out out/typer
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from maniskill_tidy.models.checkpoints import served_segmenter
from maniskill_tidy.perception.instances import Mask2D
from maniskill_tidy.perception.object_space import ObjectSpace, type_votes
from maniskill_tidy.perception.tracks import back_project
from maniskill_tidy.policies.pixels import find_masks, mask_classes, start_threshold
from maniskill_tidy.tasks.dataset import load_dataset

SIZE = 32  # crop side, pixels
CONTEXT = 1.4  # the crop's side over the mask's larger extent
DEPTH_SCALE = 0.1  # metres: relative depth is divided by this and clipped to +-3


def crop(rgb: np.ndarray, depth: np.ndarray, mask: Mask2D, intrinsics, extrinsics,
         votes: np.ndarray, score: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(5, SIZE, SIZE) uint8/int8-ranged image and the scalar features of one mask."""
    rows, cols = np.nonzero(mask.mask)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    side = max(r1 - r0, c1 - c0) * CONTEXT + 4
    cr, cc = (r0 + r1) / 2, (c0 + c1) / 2
    idx = (np.arange(SIZE) + 0.5) / SIZE * side - side / 2
    rr = np.clip((cr + idx).astype(int), 0, depth.shape[0] - 1)
    cc_ = np.clip((cc + idx).astype(int), 0, depth.shape[1] - 1)
    d = depth[np.ix_(rr, cc_)]
    med = float(np.median(depth[rows, cols]))
    image = np.empty((5, SIZE, SIZE), np.float32)
    image[:3] = rgb[np.ix_(rr, cc_)].transpose(2, 0, 1) / 255.0
    image[3] = mask.mask[np.ix_(rr, cc_)]
    image[4] = np.clip((d - med) / DEPTH_SCALE, -3, 3) / 3
    fx = float(np.asarray(intrinsics)[0, 0])
    size = np.sqrt(len(rows)) * med / fx  # metres, the mask's square-root area
    pts = back_project(rows, cols, depth, intrinsics, extrinsics)
    height = float(np.median(pts[:, 2]))
    scalars = np.concatenate([[np.log(size + 1e-3), height, med, score], votes])
    return image.astype(np.float16), scalars.astype(np.float32)


def mask_votes(mask: Mask2D, labels: np.ndarray, margins: np.ndarray, object_ids) -> np.ndarray:
    """The segmenter's margin-weighted votes over the pickupable types under the mask, per
    pixel of the mask."""
    pickupable = np.zeros(256, bool)
    pickupable[object_ids] = True
    votes, _ = type_votes(mask, labels, margins, pickupable)
    return votes[object_ids].astype(np.float32) / max(int(mask.mask.sum()), 1)


def truth_label(mask: Mask2D, cls: np.ndarray, instance: np.ndarray, index: np.ndarray) -> int:
    """The type index of the object the mask lies on (half its pixels or more), else "none"
    (the last index)."""
    inst = instance[mask.mask]
    ids, n = np.unique(inst[inst > 0], return_counts=True)
    if len(ids):
        j = int(np.argmax(n))
        if n[j] >= 0.5 * mask.mask.sum():
            t = index[int(cls[instance == ids[j]][0])]
            if t >= 0:
                return int(t)
    return len(index[index >= 0])


class MaskTyper(nn.Module):
    """Three convolution blocks over the crop, pooled, beside the scalars, to the types and
    "none"."""

    def __init__(self, scalars: int, types: int, width: int = 32) -> None:
        super().__init__()

        def block(cin: int, cout: int) -> nn.Sequential:
            return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1, bias=False),
                                 nn.BatchNorm2d(cout), nn.ReLU(inplace=True),
                                 nn.MaxPool2d(2))  # fmt: skip

        self.features = nn.Sequential(
            block(5, width), block(width, 2 * width), block(2 * width, 4 * width),
            nn.AdaptiveAvgPool2d(1), nn.Flatten(),
        )  # fmt: skip
        self.head = nn.Sequential(
            nn.Linear(4 * width + scalars, 128), nn.ReLU(inplace=True), nn.Linear(128, types + 1)
        )

    def forward(self, image: torch.Tensor, scalars: torch.Tensor) -> torch.Tensor:
        return self.head(torch.cat([self.features(image), scalars], dim=1))


def build_crops(args: argparse.Namespace) -> None:
    runtime, sha, card = served_segmenter(Path(args.weights), 2)
    threshold = start_threshold(card)
    _, _, object_ids = mask_classes()
    index = np.full(256, -1)
    index[object_ids] = np.arange(len(object_ids))
    houses = load_dataset(Path(args.dataset), args.split).houses
    images, scalars, labels, frames = [], [], [], []
    shards = sorted(Path(args.data).glob("house_*.npz"))
    for shard in tqdm(shards, desc=f"{args.split} crops", unit="house"):
        space = ObjectSpace(houses[shard.stem])
        with np.load(shard) as z:
            n = len(z["rgb"])
            ks = (np.linspace(0, n - 1, args.per).round().astype(int) if args.per
                  else np.arange(0, n, args.every))  # fmt: skip
            f = {k: z[k][ks] for k in ("rgb", "depth_mm", "cls", "instance", "intrinsics",
                                       "extrinsics")}  # fmt: skip
        depth = f["depth_mm"].astype(np.float32) / 1000
        labs, margins = runtime(f["rgb"], depth)
        for j in range(len(ks)):
            K, E = f["intrinsics"][j], f["extrinsics"][j]
            _, found, _ = find_masks(space, labs[j], margins[j], depth[j], K, E, threshold)
            for m in found:
                v = mask_votes(m, labs[j], margins[j], object_ids)
                im, sc = crop(f["rgb"][j], depth[j], m, K, E, v, m.score)
                images.append(im)
                scalars.append(sc)
                labels.append(truth_label(m, f["cls"][j], f["instance"][j], index))
                frames.append(f"{shard.stem}:{int(ks[j])}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    y = np.asarray(labels, np.int64)
    tmp = out / f"crops_{args.split}.tmp.npz"
    np.savez(tmp, image=np.stack(images), scalars=np.stack(scalars), label=y,
             frame=np.asarray(frames))  # fmt: skip
    tmp.rename(out / f"crops_{args.split}.npz")
    none = int((y == len(object_ids)).sum())
    print(f"{len(y)} masks from {len(shards)} houses, {none} on no object; segmenter {sha[:12]}")


def train(args: argparse.Namespace) -> None:
    out = Path(args.out)
    torch.manual_seed(args.seed)
    torch.set_num_threads(2)
    tr, va = (np.load(out / f"crops_{s}.npz") for s in ("train", "val"))
    types = int(tr["scalars"].shape[1] - 4)
    x, s, y = (torch.from_numpy(tr[k].astype(np.float32 if k != "label" else np.int64))
               for k in ("image", "scalars", "label"))  # fmt: skip
    xv, sv, yv = (torch.from_numpy(va[k].astype(np.float32 if k != "label" else np.int64))
                  for k in ("image", "scalars", "label"))  # fmt: skip
    model = MaskTyper(s.shape[1], types, args.width)
    counts = torch.bincount(y, minlength=types + 1).float()
    weight = (counts.sum() / (counts + 1)) ** 0.5
    loss_fn = nn.CrossEntropyLoss(weight=weight / weight.mean())
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    steps = args.epochs * (len(y) // args.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, args.lr, total_steps=steps)
    best, curve, start = -1.0, [], time.perf_counter()
    for epoch in range(1, args.epochs + 1):
        model.train()
        order = torch.randperm(len(y))
        total = 0.0
        for b in tqdm(range(len(y) // args.batch), desc=f"epoch {epoch}", leave=False):
            i = order[b * args.batch : (b + 1) * args.batch]
            xi = x[i]
            if args.flip:
                flip = torch.rand(len(i)) < 0.5
                xi[flip] = xi[flip].flip(-1)
            loss = loss_fn(model(xi, s[i]), y[i])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss)
        model.eval()
        with torch.inference_mode():
            pred = torch.cat([model(xv[k : k + 1024], sv[k : k + 1024]).argmax(1)
                              for k in range(0, len(yv), 1024)])  # fmt: skip
        obj = yv < types
        acc = float((pred[obj] == yv[obj]).float().mean())
        none_acc = float((pred[~obj] == types).float().mean())
        vote = sv[:, 4:].argmax(1)
        vote_acc = float((vote[obj] == yv[obj]).float().mean())
        row = {"epoch": epoch, "train_loss": total / (len(y) // args.batch),
               "val_type_accuracy": round(acc, 4), "val_none_accuracy": round(none_acc, 4),
               "votes_type_accuracy": round(vote_acc, 4)}  # fmt: skip
        curve.append(row)
        print(json.dumps(row))
        if acc > best:
            best = acc
            torch.save({"state": model.state_dict(), "scalars": int(s.shape[1]), "types": types,
                        "width": args.width}, out / "typer.tmp.pt")  # fmt: skip
            (out / "typer.tmp.pt").rename(out / "typer.pt")
    digest = hashlib.sha256((out / "crops_train.npz").read_bytes()).hexdigest()
    card = {"curve": curve, "best_val_type_accuracy": best, "train_seconds":
            round(time.perf_counter() - start, 1), "crops_train_sha256": digest,
            "crops": {"train": len(y), "val": len(yv)}, "config": vars(args)}  # fmt: skip
    (out / "card.json").write_text(json.dumps(card, indent=1, default=str))


def load_typer(folder: Path) -> MaskTyper:
    saved = torch.load(Path(folder) / "typer.pt", weights_only=True)
    model = MaskTyper(saved["scalars"], saved["types"], saved["width"])
    model.load_state_dict(saved["state"])
    return model.eval()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    c = sub.add_parser("crops", help="the masks agents make on segmenter-data frames, cropped")
    c.add_argument("weights", help="a trained segmenter's folder, e.g. agents/segmenter-v2")
    c.add_argument("--data", required=True, help="segmenter-data frames of one split")
    c.add_argument("--dataset", default="data/tidy120", help="the houses they were rendered in")
    c.add_argument("--split", default="train")
    c.add_argument("--per", type=int, default=0, help="frames per house, evenly spaced")
    c.add_argument("--every", type=int, default=2, help="without --per: every n-th frame")
    c.add_argument("--out", default="out/typer")
    t = sub.add_parser("train", help="train the typer on crops_train, select on crops_val")
    t.add_argument("--out", default="out/typer")
    t.add_argument("--epochs", type=int, default=12)
    t.add_argument("--batch", type=int, default=256)
    t.add_argument("--lr", type=float, default=3e-3)
    t.add_argument("--width", type=int, default=32)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--flip", action="store_true", help="mirror half the crops left-right")
    args = ap.parse_args()
    build_crops(args) if args.command == "crops" else train(args)


if __name__ == "__main__":
    main()
