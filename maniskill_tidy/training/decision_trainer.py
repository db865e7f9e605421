"""Behaviour cloning of the hierarchical decision (the paper's Eq. 2) from demonstrations.

``maniskill-tidy train agents/hangrcom.yaml --setting I``:

1. makes the demonstrations with features if they are missing (``training/decision_data.py``,
   resumable per house);
2. runs the frozen perception model (``agents/perception/...``) over every row once and caches
   the features (sv, sm, and fd, fp of the most likely misplaced detection) in the work folder;
3. trains one :class:`AgentDecision` per agent of the setting's team on whole episodes
   (HanGrCom needs every agent's step together): Loss_subtask + Loss_subgoal, all weights 1,
   cross-entropy on every head, a head without a label (no object in an Explore sub-task)
   left out. A ``hard_fraction`` of the batches runs HanGrCom's inference mode (thresholded
   links and groups) so that training meets what evaluation runs;
4. keeps the epoch with the best validation loss in inference mode, checkpointing every epoch
   atomically (a rerun resumes), and writes the fp16 weights, the config and a model card with
   every head's validation accuracy, the training time and the data's hashes.

The same seed gives the same weights.
"""

from __future__ import annotations

import copy
import io
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.models.checkpoints import save_decision, weights_sha256
from maniskill_tidy.models.decision import (
    TeamDecision,
)
from maniskill_tidy.policies.agent_config import AgentConfig, TrainSettings
from maniskill_tidy.tasks.teams import SETTINGS
from maniskill_tidy.training.decision_card import model_card, split_size
from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features
from maniskill_tidy.training.decision_features import Rows, embed_split, used_input
from maniskill_tidy.training.decision_metrics import bc_loss, evaluate, selection_score
from maniskill_tidy.training.house_jobs import UNRECORDED, differing

# 5: the per-type misplaced probabilities (models.decision.suspects)


# ------------------------------------------------------------------- training
def _seeded(seed: int) -> None:
    torch.manual_seed(seed)
    np.random.seed(seed)


def fit(
    model: TeamDecision, train: Rows, val: Rows, s: TrainSettings, checkpoint: Path,
    progress: bool = True,
) -> dict:  # fmt: skip
    """Train (resumable); leaves the best-on-val weights (``s.select``, inference mode) in
    ``model``."""
    optimiser = torch.optim.Adam(model.parameters(), lr=s.lr)
    rng = np.random.default_rng(s.seed)
    # a checkpoint made with another model or other settings is started over, not resumed
    key = json.dumps([asdict(model.cfg), {**asdict(s), "epochs": None, "patience": None}])
    state = {"epoch": 0, "best": float("inf"), "best_epoch": 0, "best_state": None,
             "curve": [], "seconds": 0.0}  # fmt: skip
    if checkpoint.is_file():
        saved = torch.load(checkpoint, weights_only=False)
        if saved["data"] == [train.hash, val.hash] and saved.get("settings") == key:
            model.load_state_dict(saved["model"])
            optimiser.load_state_dict(saved["optimiser"])
            rng.bit_generator.state = saved["rng"]
            torch.set_rng_state(saved["torch_rng"])
            state = saved["state"]
    bar = tqdm(total=s.epochs, initial=state["epoch"], desc="behaviour cloning", unit="epoch",
               disable=not progress)  # fmt: skip
    from maniskill_tidy.common.provenance import code_version

    while state["epoch"] < s.epochs and state["epoch"] - state["best_epoch"] < s.patience:
        started = time.perf_counter()
        model.train()
        order = rng.permutation(train.episodes)
        total = 0.0
        for i in range(0, len(order), s.batch):
            xs, present, ys = train.batch(order[i : i + s.batch])
            out, info = model(xs, present, hard=bool(rng.random() < s.hard_fraction), labels=ys)
            loss = bc_loss(out, ys) + info["aux"]
            optimiser.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 5.0)
            optimiser.step()
            total += loss.item()
        val_metrics = evaluate(model, val, hard=True)
        state["epoch"] += 1
        state["seconds"] += time.perf_counter() - started
        state["code_version"] = code_version()  # the card names the code that trained, not a rerun
        state["curve"].append({"epoch": state["epoch"], "train": total / -(-len(order) // s.batch),
                               "val": val_metrics["loss"]})  # fmt: skip
        score = selection_score(val_metrics, s.select)
        if score < state["best"]:
            state.update(best=score, best_epoch=state["epoch"],
                         best_state=copy.deepcopy(model.state_dict()))  # fmt: skip
        buf = io.BytesIO()
        torch.save({"model": model.state_dict(), "optimiser": optimiser.state_dict(),
                    "rng": rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
                    "state": state, "data": [train.hash, val.hash], "settings": key},
                   buf)  # fmt: skip
        write_atomic(checkpoint, buf.getvalue())
        bar.update(1)
        bar.set_postfix(
            train=f"{state['curve'][-1]['train']:.3f}", val=f"{val_metrics['loss']:.3f}",
            best_epoch=state["best_epoch"],
        )  # fmt: skip
    bar.close()
    model.load_state_dict(state["best_state"])
    return state


def demos_folder(cfg: AgentConfig, setting: str, split: str) -> Path:
    return Path(cfg.demos) / f"setting_{setting}" / split


def train_decision(config: Path, setting: str, progress: bool = True) -> dict:
    """Demos (if missing), features, behaviour cloning and the model card; returns the card."""
    cfg = AgentConfig.load(config)
    also = _check(cfg, config, setting)
    settings = cfg.settings()
    manifests = {}
    for split, demo in (("train", cfg.train_demos), ("val", cfg.val_demos)):
        manifests[split] = build_demo_features(
            Path(cfg.demos), cfg.dataset, DemoConfig(setting=setting, split=split, **demo),
            workers=cfg.workers, progress=progress,
        )  # fmt: skip
    work = Path(cfg.work) / f"setting_{setting}"
    perception = Path(cfg.perception)
    decision = cfg.decision()

    def used(rows: Rows) -> Rows:  # the cache holds every model's inputs; keep what this reads
        rows.x = {k: v for k, v in rows.x.items() if used_input(k, decision)}
        return rows

    train = used(embed_split(demos_folder(cfg, setting, "train"), perception, work, progress))
    for root, folder in zip(cfg.also_train, also, strict=True):
        manifests[f"train, also {root}"] = json.loads((folder / "manifest.json").read_text())
        same_demo_conditions(manifests["train"], manifests[f"train, also {root}"], folder)
        train = train + used(embed_split(folder, perception, work, progress))
    val = used(embed_split(demos_folder(cfg, setting, "val"), perception, work, progress))
    train, val = train.every(decision.decide_every), val.every(decision.decide_every)
    _seeded(settings.seed)
    model = TeamDecision(decision, train.index.shape[-1])
    state = fit(model, train, val, settings, work / f"{cfg.name}.ckpt", progress)
    card = _card(cfg, config, setting, model, settings, manifests, train, val, state)
    folder = Path(cfg.out) / f"setting_{setting}"
    save_decision(model, folder, {"name": cfg.name, "perception": str(perception)})
    card["weights_sha256"] = weights_sha256(folder)  # checked when a team loads it
    write_atomic(folder / "card.json", json.dumps(card, indent=1, sort_keys=True).encode())
    write_atomic(folder / "MODEL_CARD.md", model_card(card).encode())
    return card


def _check(cfg: AgentConfig, config: Path, setting: str) -> list[Path]:
    """Refuse a setting, team or teacher the config cannot train; returns the also_train
    folders, each checked to hold demonstrations."""
    if setting not in SETTINGS:
        raise ValueError(f"unknown setting {setting!r}; expected one of {sorted(SETTINGS)}")
    if cfg.team is not None:
        from maniskill_tidy.policies import team_class

        if setting != "I":
            raise ValueError(f"{config}: a team of its own ({cfg.team}) is trained with "
                             "--setting I and played in every setting")  # fmt: skip
        for split in (cfg.train_demos, cfg.val_demos):
            teacher = split.get("teacher", "expert")
            if getattr(team_class(teacher), "team_override", None) != cfg.team:
                raise ValueError(f"{config}: teacher {teacher!r} does not play with the team "
                                 f"{cfg.team}; expected a teacher with that team")  # fmt: skip
    also = [Path(root) / f"setting_{setting}" / "train" for root in cfg.also_train]
    for folder in also:
        if not (folder / "manifest.json").is_file():
            raise FileNotFoundError(f"{config}: also_train {folder} has no demonstrations; make "
                                    "them with the config that owns them first")  # fmt: skip
    return also


def same_demo_conditions(train: dict, also: dict, folder: Path) -> None:
    """Refuse to add demonstrations made under other conditions than the config's own: a
    teacher under other decision rules (``Team.rules``) would teach two teachers at once, and
    another look (``env``) would train one model on two renderers' views. A manifest made
    before a field reads as ``check_same_config`` reads it (``UNRECORDED``)."""
    differ = differing(train, also, UNRECORDED)
    theirs, ours = (", ".join(f"{k} {m.get(k, UNRECORDED[k])!r}" for k in differ)
                    for m in (also, train))  # fmt: skip
    if differ:
        raise ValueError(f"also_train {folder} was made with {theirs}, the config's "
                         f"demonstrations with {ours}; expected the same (delete the "
                         "older folder and make it again)")  # fmt: skip


DEMO_FIELDS = ("demos_hash", "teacher", "trajectories", "rows", "teacher_success", "seconds",
               "starts", "tasks", "student", "teacher_rules")  # fmt: skip


def _card(cfg, config, setting, model, settings, manifests, train, val, state) -> dict:
    """The card's figures: what was trained on what, for how long, and its val figures."""
    from maniskill_tidy.common.provenance import code_version

    return {
        "name": cfg.name,
        "setting": setting,
        "config": str(config),
        "decision": asdict(model.cfg),
        "train_settings": asdict(settings),
        "parameters_per_agent": sum(p.numel() for p in model.agents[0].parameters()),
        "agents": len(model.agents),
        "perception": str(Path(cfg.perception)),
        "demos": {
            split: {k: m[k] for k in DEMO_FIELDS if k in m} for split, m in manifests.items()
        },
        "features": {"train": train.hash, "val": val.hash},
        "full_trajectories": split_size(cfg.dataset, "train") * 50,
        "epochs_run": state["epoch"],
        "best_epoch": state["best_epoch"],
        "train_seconds": round(state["seconds"], 1),
        "curve": state["curve"],
        "val_inference_mode": evaluate(model, val, hard=True),
        "val_training_mode": evaluate(model, val, hard=False),
        "code_version": state.get("code_version", code_version()),
        "notes": cfg.notes.strip(),
        "act": asdict(cfg.acting()),
    }
