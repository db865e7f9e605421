"""The perception modules' figures on a split, next to trivial baselines, and a picture.

Figures (``perception_metrics``), each next to the baseline a module must beat:

- room classifier accuracy | majority room of the train frames;
- misplaced-object detector precision, recall, F1 (misplaced = positive) against ``D`` on the
  objects the agents saw | "always misplaced" and the per-type prior (misplaced when the
  type was misplaced in most train detections);
- receptacle predictor: share of top-1 receptacle types that are reasonable for the object
  *and* exist in its house (and share reasonable by ``D`` alone), same for the top-1 room |
  the most frequent answer in train (global prior) and per object type (type prior);
- scene encoder: query accuracy and F1 on the positive answers | per-query prior.

Baselines come from ``priors`` computed on the train views at training time and shipped in
the agent folder, so the report needs only the split's views and the checkpoints.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog


def compute_priors(train) -> dict:
    """Trivial baselines' statistics from the train views (a ``Views``)."""
    k = len(load_catalog().categories)
    kinds = train.det_type.numpy()
    misplaced = train.misplaced.numpy()
    rec = train.receptacles.numpy()
    rooms = train.rooms.numpy()
    type_misplaced, type_receptacle, type_room = {}, {}, {}
    for t in np.unique(kinds):
        sel = kinds == t
        type_misplaced[int(t)] = float(misplaced[sel].mean())
        type_receptacle[int(t)] = int(rec[sel].sum(axis=0).argmax())
        type_room[int(t)] = int(rooms[sel].sum(axis=0).argmax())
    return {
        "room_majority": int(np.bincount(train.room.numpy(), minlength=4).argmax()),
        "misplaced_rate": float(misplaced.mean()),
        "type_misplaced": type_misplaced,
        "receptacle_global": int(rec.sum(axis=0).argmax()),
        "room_global": int(rooms.sum(axis=0).argmax()),
        "type_receptacle": type_receptacle,
        "type_room": type_room,
        "query_rate": train.answers.numpy()
        .reshape(-1, train.answers.shape[1], k)
        .mean(axis=0)
        .round(4)
        .tolist(),
    }


def _prf(pred: np.ndarray, truth: np.ndarray) -> dict:
    tp = float((pred & truth).sum())
    precision = tp / max(float(pred.sum()), 1.0)
    recall = tp / max(float(truth.sum()), 1.0)
    f1 = 2 * precision * recall / max(precision + recall, 1e-9)
    return {"precision": precision, "recall": recall, "f1": f1}


def _type_lookup(table: dict, kinds: np.ndarray, default):
    return np.array([table.get(str(t), table.get(int(t), default)) for t in kinds])


@torch.no_grad()
def perception_metrics(model, views, priors: dict, batch: int = 512) -> dict:
    """Every figure of the module docstring for ``views`` (a ``Views``), model and baselines."""
    from maniskill_tidy.training.perception_trainer import embed_frames

    model.eval()
    embed_frames(model, views)
    out: dict = {"frames": views.frames, "detections": views.detections}
    # room classifier
    logits = torch.cat(
        [model.room_classifier(views.seen[i : i + batch], views.sv[i : i + batch])
         for i in range(0, views.frames, batch)]
    )  # fmt: skip
    room_pred, room_true = logits.argmax(1).numpy(), views.room.numpy()
    out["room"] = {
        "accuracy": float((room_pred == room_true).mean()),
        "majority": float((room_true == priors["room_majority"]).mean()),
        "confusion": np.array(
            [[int(((room_true == a) & (room_pred == b)).sum()) for b in range(4)] for a in range(4)]
        ).tolist(),
    }
    # detector and predictor
    f = views.det_frame
    scores, rec_top, room_top = [], [], []
    for i in range(0, views.detections, batch):
        s = slice(i, i + batch)
        r = model.reason(
            views.sv[f[s]], views.sr[f[s]], views.det_type[s], views.det_rest[s],
            views.det_numeric[s],
        )  # fmt: skip
        scores.append(r.det.softmax(1)[:, 1])
        rec_top.append(r.receptacle.argmax(1))
        room_top.append(r.room.argmax(1))
    score = torch.cat(scores).numpy() if scores else np.zeros(0)
    truth = views.misplaced.numpy().astype(bool)
    kinds = views.det_type.numpy()
    type_prior = _type_lookup(priors["type_misplaced"], kinds, priors["misplaced_rate"]) > 0.5
    out["detector"] = {
        **_prf(score > 0.5, truth),
        "always_misplaced": _prf(np.ones_like(truth), truth),
        "type_prior": _prf(type_prior, truth),
        "misplaced_share": float(truth.mean()) if len(truth) else 0.0,
        "pr_curve": _pr_curve(score, truth),
    }
    rec = views.receptacles.numpy().astype(bool)
    rec_d = views.raw["det_receptacles_d"].astype(bool)
    rooms = views.rooms.numpy().astype(bool)
    top = torch.cat(rec_top).numpy() if rec_top else np.zeros(0, int)
    rtop = torch.cat(room_top).numpy() if room_top else np.zeros(0, int)
    n = np.arange(len(top))
    type_rec = _type_lookup(priors["type_receptacle"], kinds, priors["receptacle_global"])
    type_room = _type_lookup(priors["type_room"], kinds, priors["room_global"])
    out["receptacle"] = {
        "top1_reasonable_in_house": float(rec[n, top].mean()) if len(n) else 0.0,
        "top1_reasonable": float(rec_d[n, top].mean()) if len(n) else 0.0,
        "global_prior": float(rec[:, priors["receptacle_global"]].mean()) if len(n) else 0.0,
        "type_prior": float(rec[n, type_rec].mean()) if len(n) else 0.0,
        "room_top1_reasonable_in_house": float(rooms[n, rtop].mean()) if len(n) else 0.0,
        "room_global_prior": float(rooms[:, priors["room_global"]].mean()) if len(n) else 0.0,
        "room_type_prior": float(rooms[n, type_room].mean()) if len(n) else 0.0,
    }
    # scene encoder queries
    q_logits = torch.cat(
        [model.queries(model.sm(views.crop[i : i + batch])) for i in range(0, views.frames, batch)]
    )
    answers = views.answers.numpy().astype(bool)
    pred = q_logits.numpy() > 0
    rate = np.broadcast_to(np.asarray(priors["query_rate"])[None], answers.shape)
    prior = rate > 0.5
    out["scene"] = {
        "accuracy": float((pred == answers).mean()),
        "f1": _prf(pred, answers)["f1"],
        "prior_accuracy": float((prior == answers).mean()),
        "prior_f1": _prf(prior, answers)["f1"],
        "positive_share": float(answers.mean()),
        "average_precision": average_precision(q_logits.numpy().ravel(), answers.ravel()),
        "prior_average_precision": average_precision(rate.ravel(), answers.ravel()),
    }
    return out


def average_precision(score: np.ndarray, truth: np.ndarray) -> float:
    """Mean precision at the rank of every positive, best score first (ties in input order)."""
    order = np.argsort(-score, kind="stable")
    hits = truth[order].astype(bool)
    if not hits.any():
        return 0.0
    precision = np.cumsum(hits) / np.arange(1, len(hits) + 1)
    return float(precision[hits].mean())


def _pr_curve(score: np.ndarray, truth: np.ndarray, points: int = 50) -> list[list[float]]:
    curve = []
    for th in np.linspace(0.02, 0.98, points):
        m = _prf(score >= th, truth)
        curve.append([round(m["recall"], 4), round(m["precision"], 4)])
    return curve


# Every figure of a variant's metrics (``SPLIT_metrics.json``): its row name, its path, and
# whether it is a headline figure (the side-by-side table of several agent folders shows those).
FIGURES = (
    ("room classifier accuracy", ("room", "accuracy"), True),
    ("detector precision (misplaced)", ("detector", "precision"), True),
    ("detector recall (misplaced)", ("detector", "recall"), True),
    ("detector f1 (misplaced)", ("detector", "f1"), True),
    ("receptacle top-1 reasonable & in house", ("receptacle", "top1_reasonable_in_house"), True),
    ("receptacle top-1 reasonable (D only)", ("receptacle", "top1_reasonable"), False),
    ("room top-1 reasonable & in house", ("receptacle", "room_top1_reasonable_in_house"), True),
    ("scene-encoder query accuracy", ("scene", "accuracy"), False),
    ("scene-encoder query F1 (positives)", ("scene", "f1"), True),
    ("scene-encoder query average precision", ("scene", "average_precision"), True),
)


def baseline(metrics: dict, group: str, key: str) -> str:
    """The trivial baselines a figure is read against, as ``metrics`` records them."""
    m = metrics[group]
    if group == "room":
        return f"{m['majority']:.3f} (majority room)"
    if group == "detector":
        return f"{m['always_misplaced'][key]:.3f} always / {m['type_prior'][key]:.3f} type prior"
    if group == "scene":
        return f"{m['prior_' + key]:.3f} (per-query prior)"
    prefix = {"top1_reasonable_in_house": "", "room_top1_reasonable_in_house": "room_"}
    if key not in prefix:
        return ""
    return (f"{m[prefix[key] + 'global_prior']:.3f} global / "
            f"{m[prefix[key] + 'type_prior']:.3f} type prior")  # fmt: skip


def format_report(results: dict[str, dict], split: str) -> str:
    """A markdown table: each figure with and without knowledge, next to its baselines."""
    a, b = results.get("knowledge"), results.get("no-knowledge")
    rows = [
        f"| {split} split ({a['frames']} frames, {a['detections']} detections) | with knowledge "
        "| w/o Know. | trivial baseline |",
        "|---|---|---|---|",
    ]
    for name, (group, key), _ in FIGURES:
        vals = [f"{r[group][key]:.3f}" if r else "-" for r in (a, b)]
        rows.append(f"| {name} | {vals[0]} | {vals[1]} | {baseline(a, group, key)} |")
    return "\n".join(rows)


def format_beside(results: dict[str, dict[str, dict]], split: str) -> str:
    """A markdown table of the headline figures of several agent folders (``results``: name ->
    variant -> metrics), each variant's columns side by side: one model trained and tested on
    each look, for instance."""
    names = list(results)
    variants = [v for v in ("knowledge", "no-knowledge") if all(v in r for r in results.values())]
    label = {"knowledge": "with knowledge", "no-knowledge": "w/o Know."}
    head = [f"{label[v]}, {n}" for v in variants for n in names]
    rows = [f"| {split} split | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    counts = [f"{results[n][v]['frames']} / {results[n][v]['detections']}"
              for v in variants for n in names]  # fmt: skip
    rows.append("| frames / detections | " + " | ".join(counts) + " |")
    for name, (group, key), _ in (f for f in FIGURES if f[2]):
        vals = [f"{results[n][v][group][key]:.3f}" for v in variants for n in names]
        rows.append(f"| {name} | " + " | ".join(vals) + " |")
    return "\n".join(rows)


def draw_report(results: dict[str, dict], path: Path) -> None:
    """Room-classifier confusion matrix and the detector's precision-recall curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.6))
    conf = np.asarray(results["knowledge"]["room"]["confusion"], dtype=float)
    norm = conf / np.maximum(conf.sum(axis=1, keepdims=True), 1)
    ax1.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    for i in range(4):
        for j in range(4):
            ax1.text(j, i, f"{int(conf[i, j])}", ha="center", va="center",
                     color="white" if norm[i, j] > 0.5 else "black")  # fmt: skip
    ax1.set_xticks(range(4), ROOM_TYPES, rotation=20)
    ax1.set_yticks(range(4), ROOM_TYPES)
    ax1.set_xlabel("predicted room")
    ax1.set_ylabel("true room")
    acc = results["knowledge"]["room"]["accuracy"]
    ax1.set_title(f"room classifier (accuracy {acc:.3f})")
    for variant, style in (("knowledge", "-"), ("no-knowledge", "--")):
        if variant in results:
            curve = np.asarray(results[variant]["detector"]["pr_curve"])
            f1 = results[variant]["detector"]["f1"]
            label = f"{'with knowledge' if variant == 'knowledge' else 'w/o Know.'} (F1 {f1:.3f})"
            ax2.plot(curve[:, 0], curve[:, 1], style, label=label)
    base = results["knowledge"]["detector"]
    ax2.scatter([base["type_prior"]["recall"]], [base["type_prior"]["precision"]], marker="x",
                color="gray", label="type prior")  # fmt: skip
    ax2.axhline(base["misplaced_share"], color="gray", lw=0.8, ls=":", label="always misplaced")
    ax2.set_xlim(0, 1.02)
    ax2.set_ylim(0, 1.02)
    ax2.set_xlabel("recall (misplaced)")
    ax2.set_ylabel("precision")
    ax2.set_title("misplaced-object detector (GT segmentation as detector)")
    ax2.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_json(path: Path, payload: dict) -> None:
    from maniskill_tidy.common.files import write_atomic

    write_atomic(path, json.dumps(payload, indent=1, sort_keys=True).encode())


def report(agents: Path, dataset: Path, split: str, work: Path, workers: int = 2) -> str:
    """Evaluate both variants of ``agents`` on ``split``; writes SPLIT.md, SPLIT.json and
    SPLIT.png in ``agents`` and returns the table."""
    from maniskill_tidy.models.checkpoints import load_perception
    from maniskill_tidy.tasks.dataset import read_manifest
    from maniskill_tidy.training.perception_data import ViewsConfig, build_views, load_views
    from maniskill_tidy.training.perception_trainer import VARIANTS, Views

    cards = {}
    for variant in VARIANTS:
        path = agents / variant / "card.json"
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} not found; train the agents with `maniskill-tidy train perception` "
                "(`--env HeteroTidy-v1` for v1's, as `make train`)"
            )
        cards[variant] = json.loads(path.read_text())
    card = cards["knowledge"]
    have = read_manifest(dataset)["dataset_hash"]
    if have != card["dataset_hash"]:
        raise ValueError(
            f"{dataset} has dataset hash {have[:12]}, the agents were trained on "
            f"{card['dataset_hash'][:12]}: pass --dataset with the dataset they were trained on"
        )
    cfg = card["config"]
    build_views(
        work / "views",
        str(dataset),
        ViewsConfig(
            split,
            cfg["tasks_per_house"][split],
            cfg["every"],
            seed=cfg["seed"],
            env=cfg.get("env", "HeteroTidy-v1"),
        ),
        workers=workers,
    )
    views = Views(load_views(work / "views" / split))
    priors = json.loads((agents / "knowledge" / "priors.json").read_text())
    results = {v: perception_metrics(load_perception(agents / v), views, priors) for v in VARIANTS}
    table = format_report(results, split)
    note = (
        "\n\nDetections are the renderer's ground-truth segmentation (standing in for Mask "
        "R-CNN); sv comes from a small CNN trained from scratch (standing in for ResNet); the "
        "knowledge graph counts placements in the train houses (standing in for Visual Genome)."
        f"\nAgents: code {card['code_version']}, dataset {card['dataset_hash'][:12]}, views "
        f"{card['views_hash'][:12]}, seed {card['seed']}.\n"
    )
    from maniskill_tidy.common.files import write_atomic

    write_atomic(agents / f"{split.upper()}.md", (table + note).encode())
    write_json(agents / f"{split}_metrics.json", results)
    draw_report(results, agents / f"{split}.png")
    return table + note + f"\nwrote {agents / f'{split.upper()}.md'} and {agents / f'{split}.png'}"


def beside(agents: Path, others: list[Path], split: str) -> str:
    """``agents``' figures beside those of ``others`` (each from its own ``SPLIT_metrics.json``,
    named by the look its views were rendered in); writes ``SPLIT_BESIDE.md`` in ``agents``."""
    results: dict[str, dict] = {}
    for folder in [agents, *others]:
        path = folder / f"{split}_metrics.json"
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} not found; run `maniskill-tidy perception-report --agents {folder}` first"
            )
        card = json.loads((folder / "knowledge" / "card.json").read_text())
        name = card.get("config", {}).get("env", "HeteroTidy-v1")
        results[name if name not in results else str(folder)] = json.loads(path.read_text())
    table = format_beside(results, split)
    note = (
        "\n\nEach column is a model trained on views of one look and tested on the same split's "
        "views of that look: the same houses and tasks, the expert playing them (its path "
        "differs where an action's outcome does, a thin object it cannot pick, say); "
        "`maniskill-tidy perception-report --agents "
        f"{agents} --beside {' --beside '.join(map(str, others))}`.\n"
    )
    from maniskill_tidy.common.files import write_atomic

    out = agents / f"{split.upper()}_BESIDE.md"
    write_atomic(out, (table + note).encode())
    return table + note + f"\nwrote {out}"


def draw_curves(cards: dict[str, dict], path: Path) -> None:
    """Train and val loss per epoch of every stage (both variants' reasoning stages)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("visual", "knowledge"), ("scene", "knowledge"), ("room", "knowledge"),
              ("reasoning", "knowledge"), ("reasoning", "no-knowledge")]  # fmt: skip
    panels = [(s, v) for s, v in panels if v in cards and s in cards[v]["stages"]]
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.0), squeeze=False)
    for ax, (stage, variant) in zip(axes[0], panels, strict=True):
        st = cards[variant]["stages"][stage]
        epochs = [c["epoch"] for c in st["curve"]]
        ax.plot(epochs, [c["train"] for c in st["curve"]], label="train")
        ax.plot(epochs, [c["val"] for c in st["curve"]], label="val")
        ax.axvline(st["best_epoch"], color="gray", ls=":", lw=0.8)
        title = stage if stage != "reasoning" else f"reasoning ({variant})"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("epoch")
    axes[0][0].set_ylabel("loss")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
