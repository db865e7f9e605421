"""Objects as what the floor plan does not explain (``perception/object_space.py``): how many
of the val frames' objects do its masks find, typed by the segmenter's votes, against the
segmenter's own masks? And which start score for them, beside the card's for the segmenter's
masks, gives agents the best F1? Mask AP over the pickupable types (scores as each source
gives them; for "as agents make them", the floor plan's masks' scores shifted by the card's
threshold less ``PLAN_START`` so that one threshold ranks both), then the F1, precision and
recall of the masks agents start tracks from, for a sweep of the floor plan's start score.

The segmenter runs as agents run it (its int8 graph through ONNX Runtime); ``--per`` frames
evenly spaced of each val house (the frames carry no task, the houses' floor plans come from
the dataset the frames were rendered from). ``--robots-out`` and ``--own-body`` leave robots
out of what the floor plan does not explain (research log, seventeenth part: both lower AP50),
``--furniture-out`` the pixels labelled furniture. ``--own-unclaimed`` keeps the segmenter's
own object masks wherever no kept floor-plan mask claims their pixels (not only where the plan
explains them), and ``--cut-rejected C`` also cuts each floor-plan part under ``PLAN_KEEP`` to
its pixels labelled pickupable, keeping the sub-parts that reach it and fill at least ``C`` of
their box (research log, eighteenth part). ``--true-type`` adds a row: the masks as agents
make them, each given the type of the object it covers most (a perfect second stage that types
masks, as Mask R-CNN's box head names a proposal: this bounds what a crop classifier gives).

    .venv/bin/python docs/research/probes/floor_plan_masks.py agents/segmenter-v2 \\
        --data data/segmenter/HeteroTidy-v2/val --dataset data/tidy120 --per 20
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

import mask_typer
import numpy as np
import segmenter_probe
import torch
from tqdm import tqdm
from two_stage_ceiling import true_type

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.models.checkpoints import served_segmenter
from maniskill_tidy.perception.instances import (
    Mask2D,
    coarse,
    refined,
    scored_by_relief,
    split_instances,
)
from maniskill_tidy.perception.object_space import (
    ObjectSpace,
    frame_objects,
    object_masks,
    own_masks,
    unexplained,
)
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.perception.tracks import back_project, camera_position
from maniskill_tidy.policies.pixels import (
    KEEP_THRESHOLD,
    PLAN_COVERED,
    PLAN_KEEP,
    PLAN_START,
    mask_classes,
)
from maniskill_tidy.tasks.dataset import load_dataset
from maniskill_tidy.training.segmenter_trainer import truth_masks


def without_class(unexplained_px: np.ndarray, labels: np.ndarray, cls) -> np.ndarray:
    """The unexplained pixels less those the segmenter labels ``cls`` (one class id or a list,
    on its grid): robots are not in the floor plan either, nor is a piece's mesh where it
    leaves the plan's boxes, and an object beside either makes one part with it."""
    step = unexplained_px.shape[0] // labels.shape[0]
    own = np.repeat(np.repeat(np.isin(labels, cls), step, axis=0), step, axis=1)
    return unexplained_px & ~own


def near_camera(depth, intrinsics, extrinsics, radius: float) -> np.ndarray:
    """Pixels whose point lies within ``radius`` of the camera, horizontally."""
    rows, cols = np.indices(depth.shape)
    pts = back_project(rows.ravel(), cols.ravel(), depth, intrinsics, extrinsics)
    cam = camera_position(extrinsics)
    return (np.hypot(*(pts[:, :2] - cam[:2]).T) < radius).reshape(depth.shape)


def unclaimed_objects(masks, free, depth, labels, margins, pickupable, keep, start, plan_keep,
                      plan_start, covered, min_pixels, cut_rejected=None):  # fmt: skip
    """``frame_objects`` with the segmenter's own masks cut only by the kept floor-plan
    masks' pixels (and, with ``cut_rejected``, rejected parts cut to their object labels)."""
    grid = depth.shape[0] // labels.shape[0]
    parts = object_masks(free, depth, labels, margins, pickupable, min_pixels)
    plan = [m for m in parts if m.score >= plan_keep]
    if cut_rejected is not None:
        labelled = np.repeat(np.repeat(pickupable[labels], grid, 0), grid, 1)
        for m in parts:
            if m.score >= plan_keep:
                continue
            for sub in object_masks(m.mask & labelled, depth, labels, margins, pickupable,
                                    min_pixels):  # fmt: skip
                rows, cols = sub.window
                height = (rows.stop or depth.shape[0]) - (rows.start or 0)
                box = height * ((cols.stop or depth.shape[1]) - (cols.start or 0))
                if sub.score >= plan_keep and sub.area >= cut_rejected * box:
                    plan.append(sub)
    claimed = np.zeros(free.shape, bool)
    for m in plan:
        claimed |= m.mask
    own = own_masks(masks, claimed, depth, grid, pickupable, keep, covered, min_pixels)
    return plan + own, [plan_start] * len(plan) + [start] * len(own)


def retyped(typer, found, agents, frames, j, depth, labels, margins, object_ids):
    """The masks agents make (``agents``: scored as in the row), typed by the typer; and the
    same types scored by the typer's probability of them."""
    if not found:
        return [], []
    K, E = frames["intrinsics"][j], frames["extrinsics"][j]
    crops = [mask_typer.crop(frames["rgb"][j], depth, m, K, E,
                             mask_typer.mask_votes(m, labels, margins, object_ids), m.score)
             for m in found]  # fmt: skip
    images = torch.from_numpy(np.stack([c[0] for c in crops])).float()
    scalars = torch.from_numpy(np.stack([c[1] for c in crops]))
    with torch.inference_mode():
        p = torch.softmax(typer(images, scalars), 1).numpy()
    k = p[:, :-1].argmax(1)
    typed = [
        Mask2D(int(object_ids[t]), m.mask, m.score, m.box) for m, t in zip(agents, k, strict=True)
    ]
    sure = [Mask2D(int(object_ids[t]), m.mask, float(p[i, t]), m.box)
            for i, (m, t) in enumerate(zip(agents, k, strict=True))]  # fmt: skip
    return typed, sure


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("weights", help="a trained segmenter's folder, e.g. agents/segmenter-v2")
    ap.add_argument("--data", default=segmenter_probe.VAL, help="segmenter-data frames")
    ap.add_argument("--dataset", default="data/tidy120", help="the houses they were rendered in")
    ap.add_argument("--split", default="val")
    ap.add_argument("--per", type=int, default=20, help="frames per house, evenly spaced")
    ap.add_argument("--starts", default="0.3,0.35,0.4,0.45,0.5,0.55,0.6",
                    help="the floor plan's start scores to sweep")  # fmt: skip
    ap.add_argument("--robots-out", action="store_true",
                    help="leave out of the unexplained pixels those labelled robot")  # fmt: skip
    ap.add_argument("--own-body", type=float, default=0.0,
                    help="metres: leave out unexplained pixels this near the camera, "
                         "horizontally (the agent's own body)")  # fmt: skip
    ap.add_argument("--furniture-out", action="store_true",
                    help="leave out of the unexplained pixels the furniture labels")  # fmt: skip
    ap.add_argument("--own-unclaimed", action="store_true",
                    help="keep the segmenter's own masks where no kept floor-plan mask claims "
                         "their pixels")  # fmt: skip
    ap.add_argument("--cut-rejected", type=float, default=None, metavar="C",
                    help="with --own-unclaimed: cut parts under PLAN_KEEP to their object "
                         "labels; keep sub-parts filling C of their box")  # fmt: skip
    ap.add_argument("--typer", default=None, metavar="DIR",
                    help="add the masks as agents make them typed by mask_typer.py's "
                         "trained second stage in DIR")  # fmt: skip
    ap.add_argument("--true-type", action="store_true",
                    help="add the masks as agents make them, perfectly typed")  # fmt: skip
    args = ap.parse_args()
    if args.cut_rejected is not None and not args.own_unclaimed:
        ap.error("--cut-rejected: expected with --own-unclaimed")
    objects_of = (functools.partial(unclaimed_objects, cut_rejected=args.cut_rejected)
                  if args.own_unclaimed else frame_objects)  # fmt: skip
    c = seg_classes()
    robot = c.index["robot"] if args.robots_out else None
    furniture = ([i for i, n in enumerate(c.names) if n.startswith("furniture:")]
                 if args.furniture_out else None)  # fmt: skip
    runtime, _, card = served_segmenter(args.weights, 2)
    card_start = float(card["agent_threshold"]["threshold"])
    keep = min(KEEP_THRESHOLD, card_start)
    houses = load_dataset(Path(args.dataset), args.split).houses
    pickupable = segmenter_probe.pickupable_table()
    classes = [int(i) for i in np.nonzero(pickupable)[0]]
    rows: dict[str, list] = {"segmenter's masks": [], "floor plan's masks": [],
                             "as agents make them": []}  # fmt: skip
    if args.true_type:
        rows["perfectly typed"] = []
    if args.typer:
        typer = mask_typer.load_typer(Path(args.typer))
        object_ids = np.asarray(mask_classes()[2])
        rows["typer's type"], rows["typer's type, p"] = [], []
    started: dict[float, list] = {float(t): [] for t in args.starts.split(",")}
    shards = sorted(Path(args.data).glob("house_*.npz"))
    for shard in tqdm(shards, desc="houses", unit="house"):
        space = ObjectSpace(houses[shard.stem])
        with np.load(shard) as z:
            ks = np.linspace(0, len(z["rgb"]) - 1, args.per).round().astype(int)
            frames = {k: z[k][ks] for k in ("rgb", "depth_mm", "cls", "instance",
                                            "intrinsics", "extrinsics")}  # fmt: skip
        depth = frames["depth_mm"].astype(np.float32) / 1000
        labels, margins = runtime(frames["rgb"], depth)
        for j in range(len(ks)):
            d, lab, mar = depth[j], labels[j], margins[j]
            grid = d.shape[0] // lab.shape[0]
            d_g = coarse(d, grid)
            masks = scored_by_relief(
                split_instances(lab, d_g, classes, mar, -(-MIN_PIXELS // grid**2)), d_g, classes
            )
            truth = truth_masks(frames["cls"][j], frames["instance"][j], classes)
            free = unexplained(space, d, frames["intrinsics"][j], frames["extrinsics"][j])
            if args.own_body:
                free = free & ~near_camera(d, frames["intrinsics"][j], frames["extrinsics"][j],
                                           args.own_body)  # fmt: skip
            if args.robots_out:
                free = without_class(free, lab, robot)
            if args.furniture_out:
                free = without_class(free, lab, furniture)
            own = refined([m for m in masks if m.score >= keep], d, grid, MIN_PIXELS)
            rows["segmenter's masks"].append((truth, own))
            plan = object_masks(free, d, lab, mar, pickupable, MIN_PIXELS)
            rows["floor plan's masks"].append((truth, plan))
            found, starts = objects_of(
                masks, free, d, lab, mar, pickupable, keep, card_start,
                PLAN_KEEP, PLAN_START, PLAN_COVERED, MIN_PIXELS,
            )  # fmt: skip
            shift = card_start - PLAN_START
            rows["as agents make them"].append((truth, [
                Mask2D(m.cls, m.mask, m.score + (shift if s == PLAN_START else 0.0), m.box)
                for m, s in zip(found, starts, strict=True)
            ]))  # fmt: skip
            agents = rows["as agents make them"][-1][1]
            if args.true_type:
                rows["perfectly typed"].append((truth, [true_type(m, truth) for m in agents]))
            if args.typer:
                typed, sure = retyped(typer, found, agents, frames, j, d, lab, mar, object_ids)
                rows["typer's type"].append((truth, typed))
                rows["typer's type, p"].append((truth, sure))
            every, kinds = objects_of(masks, free, d, lab, mar, pickupable, keep, card_start,
                                         0.0, -1.0, PLAN_COVERED, MIN_PIXELS)  # fmt: skip
            for t, pairs in started.items():
                pairs.append((truth, [
                    Mask2D(m.cls, m.mask, 1.0, m.box) for m, kind in zip(every, kinds, strict=True)
                    if m.score >= (t if kind < 0 else card_start)
                ]))  # fmt: skip
    shape = depth.shape[1:3]
    print(f"{len(rows['as agents make them'])} frames of {len(shards)} houses")
    for name, pairs in rows.items():
        print(f"{name:24s} {segmenter_probe.scored(pairs, classes, shape)}")
    print(
        f"tracks start: the segmenter's masks at the card's {card_start:.3f}, the floor plan's at"
    )
    for t, pairs in started.items():
        line = segmenter_probe.scored(pairs, classes, shape).split("|")[1]
        print(f"  {t:.2f}: {line.split(':', 1)[1].strip()}")


if __name__ == "__main__":
    main()
