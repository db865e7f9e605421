"""The cross-look table: every look's segmenter scored on every look's test frames.

``maniskill-tidy segmenter-cross-look --segmenters agents/segmenter-v1 agents/segmenter-v2``
scores each segmenter on the test houses' frames that ``segmenter-data`` rendered in each look
(``data/segmenter/HeteroTidy-v1/test``, ``.../HeteroTidy-v2/test``), as its card scores its own
look (``segmenter_trainer.evaluate``: instances as agents make them, through the graph agents
run), and writes the table as JSON and markdown. The diagonal repeats the cards' test figures;
off it, what a segmenter trained on one look keeps on the other: how much of what it learnt is
the look.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.models import checkpoints
from maniskill_tidy.training.segmenter_trainer import evaluate, load_split

KEYS = ("AP50", "AP", "AP_small", "AP_medium", "pixel_accuracy_pickupable")


def cross_look(segmenters: list[Path], data: Path, split: str = "test",
               progress: bool = True) -> list[dict]:  # fmt: skip
    """One row per (segmenter, look of frames), the looks being ``data``'s folders that hold
    ``split`` frames."""
    looks = sorted(p.parent.parent.name for p in Path(data).glob(f"*/{split}/manifest.json"))
    if not looks:
        raise FileNotFoundError(f"{data}: no <look>/{split}/manifest.json; render the frames "
                                "with `make segmenter-data`")  # fmt: skip
    threads = torch.get_num_threads()  # what agents run: the int8 graph where one ships
    models = {Path(s): checkpoints.served_segmenter(Path(s), threads) for s in segmenters}
    rows = []
    bar = tqdm(total=len(models) * len(looks), unit="pair", disable=not progress,
               desc="cross-look")  # fmt: skip
    with bar:
        for look in looks:
            frames = load_split(Path(data) / look / split)
            manifest = json.loads((Path(data) / look / split / "manifest.json").read_text())
            for folder, (model, sha256, card) in models.items():
                scores = evaluate(model, frames)
                rows.append({"segmenter": str(folder), "trained_on": card.get("look", "?"),
                             "tested_on": look, "split": split,
                             "frames": len(frames["rgb"]), "data_hash": manifest["data_hash"],
                             "served_sha256": sha256,
                             **{k: scores[k] for k in KEYS}})  # fmt: skip
                bar.update(1)
    return rows


def markdown(rows: list[dict]) -> str:
    head = "| segmenter | trained on | tested on | frames | " + " | ".join(KEYS) + " |"
    lines = [head, "|" + "---|" * 4 + "---:|" * len(KEYS)]
    for r in rows:
        cells = [r["segmenter"], r["trained_on"], r["tested_on"], str(r["frames"])]
        lines.append("| " + " | ".join(cells + [f"{r[k]:.3f}" for k in KEYS]) + " |")
    return "\n".join(lines) + "\n"


def write_table(rows: list[dict], out: Path) -> tuple[Path, Path]:
    """``out``.json and ``out``.md, each written whole or not at all."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    js, md = out.with_suffix(".json"), out.with_suffix(".md")
    write_atomic(js, json.dumps(rows, indent=1).encode())
    write_atomic(md, markdown(rows).encode())
    return js, md
