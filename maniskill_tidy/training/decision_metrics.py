"""Behaviour cloning's loss (the paper's Eq. 2) and the validation figures a model is
selected on."""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from scipy.stats import rankdata

from maniskill_tidy.models.decision import (
    DecisionConfig,
    TeamDecision,
)
from maniskill_tidy.policies.base import OPERATIONS
from maniskill_tidy.training.decision_features import LABELS, Rows

DIRECT = ("action", "receptacle")  # w/o HierDec.'s heads


# ------------------------------------------------------------------- loss and metrics
def bc_loss(out: list[dict], ys: list[dict]) -> torch.Tensor:
    """Eq. 2 summed over the agents: Loss_subtask + Loss_subgoal, every weight 1 (w/o HierDec.:
    the cross-entropy of the low-level action and of the receptacle)."""
    total = torch.zeros(())
    for logits, y in zip(out, ys, strict=True):
        for head in logits:
            target = y[head]
            if (target >= 0).any():
                total = total + F.cross_entropy(
                    logits[head].flatten(0, 1), target.flatten(), ignore_index=-1
                )
    return total


@torch.no_grad()
def evaluate(model: TeamDecision, rows: Rows, hard: bool, batch: int = 16) -> dict:
    """Mean loss per episode batch, each head's accuracy over the labelled rows, and how well
    each operation's probability ranks the steps labelled with it (``ope_auc``: the act
    section's ``ope_threshold`` relies on that ranking, not on the argmax)."""
    model.eval()
    heads = model_heads(model.cfg)
    correct = {h: 0 for h in heads}
    count = {h: 0 for h in heads}
    losses = []
    ope_p, ope_y = [], []
    for start in range(0, rows.episodes, batch):
        xs, present, ys = rows.batch(np.arange(start, min(start + batch, rows.episodes)))
        out, info = model(xs, present, hard=hard, labels=ys)
        losses.append(float(bc_loss(out, ys) + info["aux"]))
        for logits, y in zip(out, ys, strict=True):
            for head in heads:
                ok = y[head] >= 0
                correct[head] += int((logits[head].argmax(-1)[ok] == y[head][ok]).sum())
                count[head] += int(ok.sum())
            if "ope" in logits:
                ok = y["ope"] >= 0
                ope_p.append(logits["ope"].softmax(-1)[ok])
                ope_y.append(y["ope"][ok])
    out = {
        "loss": float(np.mean(losses)),
        "accuracy": {h: correct[h] / count[h] if count[h] else None for h in heads},
        "majority": majority(rows, heads),
        "labelled": count,
    }
    if ope_p:
        p, y = torch.cat(ope_p), torch.cat(ope_y)
        out["ope_auc"] = {op: auc(p[:, i], y == i) for i, op in enumerate(OPERATIONS) if i}
    return out


def model_heads(cfg: DecisionConfig) -> tuple[str, ...]:
    """The heads a model predicts (and the card reports)."""
    return LABELS if cfg.hierarchical else DIRECT


def auc(score: torch.Tensor, positive: torch.Tensor) -> float | None:
    """Area under the ROC curve: the chance a positive scores above a negative (ties half)."""
    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    if not n_pos or not n_neg:
        return None
    ranks = torch.from_numpy(rankdata(score.numpy()))
    return float((ranks[positive].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def majority(rows: Rows, heads: tuple[str, ...] = LABELS) -> dict[str, float | None]:
    """Each head's accuracy when always answering its most frequent label (the trivial
    baseline the card compares with)."""
    out = {}
    for head in heads:
        y = rows.y[head][rows.y[head] >= 0]
        out[head] = float(torch.bincount(y).max()) / len(y) if len(y) else None
    return out


def selection_score(metrics: dict, select: str) -> float:
    """Lower is better."""
    if select == "loss":
        return metrics["loss"]
    acc, base = metrics["accuracy"], metrics["majority"]
    gains = [acc[h] - base[h] for h in acc if acc[h] is not None and base[h] is not None]
    return -float(np.mean(gains))
