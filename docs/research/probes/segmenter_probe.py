"""What the segmenter probes share: their command line (a trained segmenter's folder, the
frames to read and how many, evenly spaced) and loading both. The probes study the network, so
they run its fp16 weights in torch, not the int8 graph agents run."""

from __future__ import annotations

import argparse
from pathlib import Path

from maniskill_tidy.models import checkpoints
from maniskill_tidy.models.segmenter import Segmenter
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
