"""Mask AP of predicted instances against the renderer's, by pycocotools' COCOeval.

The pixels track's segmenter is scored as a detector is: per frame, its instances (class,
mask, score) against the ground-truth instances of the same frame, matched at IoU thresholds
0.5:0.95; AP, AP50, AP75 and AP by object size (COCO's area ranges, in pixels of our 224 px
frames: small under 32^2, medium under 96^2). Only the classes asked for count (the pickupable
types: what a team must find), and the segmenter's card counts objects an agent could act on:
ground truth under the env's visibility threshold (``MIN_PIXELS``) is ignored.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterable

import numpy as np
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from maniskill_tidy.perception.instances import Mask2D

KEYS = ("AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large")


def _rle(mask: np.ndarray) -> dict:
    rle = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    rle["counts"] = rle["counts"].decode("ascii")
    return rle


def _evaluated(frames, classes, shape, ignore_below: int):
    """COCOeval of the frames' masks (evaluated and accumulated; None when either side is
    empty) and the instance counts."""
    classes = sorted(set(int(c) for c in classes))
    images, gts, dts = [], [], []
    for image_id, (truth, predicted) in enumerate(frames, start=1):
        images.append({"id": image_id, "height": shape[0], "width": shape[1]})
        for m in truth:
            if m.cls in classes:
                rle = _rle(m.mask)
                gts.append({"id": len(gts) + 1, "image_id": image_id, "category_id": m.cls,
                            "segmentation": rle, "area": float(m.area),
                            "iscrowd": int(m.area < ignore_below),
                            "bbox": list(mask_utils.toBbox(rle))})  # fmt: skip
        for m in predicted:
            if m.cls in classes:
                dts.append({"image_id": image_id, "category_id": m.cls,
                            "segmentation": _rle(m.mask), "score": m.score})  # fmt: skip
    counts = {"images": len(images), "truth": sum(not g["iscrowd"] for g in gts),
              "ignored": sum(g["iscrowd"] for g in gts), "predicted": len(dts)}  # fmt: skip
    if not gts or not dts:
        return None, counts
    coco = COCO()
    coco.dataset = {"images": images, "annotations": gts,
                    "categories": [{"id": c} for c in classes]}  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        coco.createIndex()
        result = coco.loadRes(dts)
        ev = COCOeval(coco, result, iouType="segm")
        ev.params.catIds = classes
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    return ev, counts


def mask_ap(
    frames: Iterable[tuple[list[Mask2D], list[Mask2D]]],
    classes: Iterable[int],
    shape,
    ignore_below: int = 0,
) -> dict[str, float]:
    """``frames``: per frame (ground truth, predictions). Returns :data:`KEYS` (-1 where no
    ground truth of that size exists, as COCOeval reports it) and the instance counts.
    Ground truth smaller than ``ignore_below`` pixels is ignored as COCO ignores crowds:
    neither missed nor matched, and a prediction on it is no false positive."""
    ev, counts = _evaluated(frames, classes, shape, ignore_below)
    if ev is None:
        return {**dict.fromkeys(KEYS, 0.0 if counts["truth"] else -1.0), **counts}
    return {**{k: round(float(v), 4) for k, v in zip(KEYS, ev.stats[:6], strict=True)}, **counts}


def matches_by_class(
    frames: Iterable[tuple[list[Mask2D], list[Mask2D]]],
    classes: Iterable[int],
    shape,
    ignore_below: int = 0,
) -> dict[int, tuple[np.ndarray, np.ndarray, int]]:
    """Per class: the scores of its predicted masks that count at IoU 0.5 (not on ignored
    ground truth), whether each matched an object, and how many objects count."""
    ev, _ = _evaluated(frames, classes, shape, ignore_below)
    out: dict[int, tuple[list, list, list]] = {}
    for e in [] if ev is None else ev.evalImgs:
        if e is None or e["aRng"] != ev.params.areaRng[0]:  # "all" sizes only
            continue
        scores, hits, truths = out.setdefault(e["category_id"], ([], [], [0]))
        keep = ~e["dtIgnore"][0].astype(bool)  # IoU 0.5
        scores += list(np.asarray(e["dtScores"])[keep])
        hits += list(e["dtMatches"][0][keep] > 0)
        truths[0] += int((~e["gtIgnore"].astype(bool)).sum())
    return {c: (np.array(s, dtype=float), np.array(h, dtype=bool), t[0])
            for c, (s, h, t) in out.items()}  # fmt: skip


def best_f1(scores: np.ndarray, hits: np.ndarray, truths: int) -> dict[str, float]:
    """The score at which masks ranked by it give the best F1, with the precision and recall
    there. Masks of one score are kept or left out together (a threshold cannot part them),
    so the answer does not depend on their order."""
    if not len(scores):
        return {"threshold": 0.0, "f1": 0.0, "precision": 0.0, "recall": 0.0}
    order = np.argsort(-scores, kind="stable")
    tp = np.cumsum(hits[order].astype(float))
    precision = tp / np.arange(1, len(tp) + 1)
    recall = tp / max(truths, 1)
    f1 = 2 * precision * recall / np.maximum(precision + recall, 1e-12)
    ranked = scores[order]
    f1[:-1][ranked[:-1] == ranked[1:]] = -1.0  # inside a run of equal scores
    k = int(np.argmax(f1))
    return {"threshold": round(float(scores[order][k]), 4),
            "f1": round(float(f1[k]), 4), "precision": round(float(precision[k]), 4),
            "recall": round(float(recall[k]), 4)}  # fmt: skip


def score_threshold(
    frames: Iterable[tuple[list[Mask2D], list[Mask2D]]],
    classes: Iterable[int],
    shape,
    ignore_below: int = 0,
) -> dict[str, float]:
    """The score above which predicted masks give the best F1 at IoU 0.5 (a right type and
    mask), with the precision and recall there: where an agent that acts on masks, unlike the
    AP, must draw the line. One threshold for every class: one per class chosen on half the
    val houses scored lower F1 on the other half (``docs/research/probes/type_thresholds.py``)."""
    per_class = matches_by_class(frames, classes, shape, ignore_below).values()
    if not per_class:
        return best_f1(np.zeros(0), np.zeros(0, bool), 0)
    return best_f1(np.concatenate([s for s, _, _ in per_class]),
                   np.concatenate([h for _, h, _ in per_class]),
                   sum(t for *_, t in per_class))  # fmt: skip
