"""What the segmenter probes share: their command line (a trained segmenter's folder, the
frames to read and how many, evenly spaced) and loading both. The probes study the network, so
they run its fp16 weights in torch, not the int8 graph agents run."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import Segmenter, predict, upsample
from maniskill_tidy.perception.seg_classes import seg_classes
from maniskill_tidy.training.segmenter_trainer import load_split

VAL = "data/segmenter/HeteroTidy-v2/val"


def arguments(doc: str, data: str = VAL) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("weights", help="a trained segmenter's folder, e.g. agents/segmenter-v2")
    ap.add_argument("--data", default=data, help="segmenter-data frames")
    ap.add_argument("--frames", type=int, default=400, help="evenly spaced frames to read")
    return ap.parse_args()


def segmenter(args: argparse.Namespace) -> tuple[Segmenter, dict]:
    return checkpoints.load_segmenter(Path(args.weights))


def frames(args: argparse.Namespace, split: str = "") -> dict:
    return load_split(Path(args.data) / split, args.frames)


def labelled_objects(model: Segmenter, data: dict) -> Iterator[tuple[int, np.ndarray]]:
    """Each of the renderer's pickupable objects of ``MIN_PIXELS`` or more on the frames: its
    type and the segmenter's labels of its pixels (upsampled to the frame), for the probes
    that ask what the segmenter calls an object's pixels."""
    pickupable = pickupable_table()
    depth = data["depth_mm"].astype(np.float32) / 1000
    labels = upsample(*predict(model, data["rgb"], depth), depth.shape[1:3])[0]
    for k in range(len(labels)):
        inst, cls = data["instance"][k], data["cls"][k]
        for i in np.unique(inst[inst > 0]):
            m = inst == i
            t = int(cls[m][0])
            if pickupable[t] and m.sum() >= MIN_PIXELS:
                yield t, labels[k][m]


def pickupable_table() -> np.ndarray:
    """Label -> is it a pickupable type (background excluded), for indexing label arrays."""
    c = seg_classes()
    return np.array([c.is_pickupable(i) and i > 0 for i in range(256)])
