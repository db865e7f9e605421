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
import hashlib
import io
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from scipy.stats import rankdata
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.checkpoints import save_decision, weights_sha256
from maniskill_tidy.models.communication import TASK, scheme
from maniskill_tidy.models.decision import (
    HEADS_GOAL,
    HEADS_TASK,
    DecisionConfig,
    TeamDecision,
    crop_goal,
    crop_layout,
    suspects,
)
from maniskill_tidy.policies.agent_config import AgentConfig, TrainSettings
from maniskill_tidy.policies.base import OPERATIONS
from maniskill_tidy.tasks.teams import SETTINGS
from maniskill_tidy.training.decision_data import DemoConfig, build_demo_features

FEATURES = ("sv", "sm", "fd", "fp")  # 256-d each, cached as fp16
SCALARS = ("mis", "det", "failed")
LABELS = HEADS_TASK + HEADS_GOAL
DIRECT = ("action", "receptacle")  # w/o HierDec.'s heads
OFFSET = {"dx": 4, "dy": 4}  # -4..4 -> class 0..8


# ------------------------------------------------------------------- features of every row
@dataclass
class Rows:
    """Per-row tensors of one split, and the (episode, step, agent) -> row index."""

    x: dict[str, torch.Tensor]
    y: dict[str, torch.Tensor]
    index: torch.Tensor  # (E, T, N) row or -1
    hash: str

    @property
    def episodes(self) -> int:
        return self.index.shape[0]

    def __add__(self, other: Rows) -> Rows:
        """Both splits' rows as one (episodes of ``other`` after ours; same team size)."""
        if self.index.shape[-1] != other.index.shape[-1]:
            raise ValueError(f"rows of {self.index.shape[-1]} and {other.index.shape[-1]} agents")
        steps = max(self.index.shape[1], other.index.shape[1])
        n = len(next(iter(self.y.values())))

        def padded(index: torch.Tensor, offset: int) -> torch.Tensor:
            out = torch.full((index.shape[0], steps, index.shape[2]), -1, dtype=torch.long)
            out[:, : index.shape[1]] = torch.where(index >= 0, index + offset, -1)
            return out

        if set(self.x) != set(other.x):  # both come from one FEATURES_VERSION, so never expected
            raise ValueError(f"rows with inputs {sorted(self.x)} and {sorted(other.x)}")
        return Rows(
            {k: torch.cat([self.x[k], other.x[k]]) for k in self.x},
            {k: torch.cat([self.y[k], other.y[k]]) for k in self.y},
            torch.cat([padded(self.index, 0), padded(other.index, n)]),
            f"{self.hash}+{other.hash}",
        )

    def batch(self, episodes: np.ndarray) -> tuple[list[dict], torch.Tensor, list[dict]]:
        """Agent-wise inputs and labels (B, T, ·) of some episodes, and ``present`` (B, T, N)."""
        idx = self.index[torch.as_tensor(episodes)]
        t = int((idx >= 0).any(-1).any(0).nonzero().max()) + 1
        idx = idx[:, :t]
        present = idx >= 0
        safe = idx.clamp(min=0)
        xs, ys = [], []
        for n in range(idx.shape[-1]):
            rows = safe[:, :, n]
            xs.append({k: v[rows].float() if v.is_floating_point() else v[rows]
                       for k, v in self.x.items()})  # fmt: skip
            ys.append({k: torch.where(present[:, :, n], v[rows], -1) for k, v in self.y.items()})
        for xn, yn in zip(xs, ys, strict=True):  # the sub-task a state message carries
            task = torch.stack([yn[k] for k in TASK], dim=-1)
            xn["prev_task"] = torch.cat([torch.full_like(task[:, :1], -1), task[:, :-1]], dim=1)
        return xs, present, ys


FEATURES_VERSION = 5  # 2: the crop's layout; 3: its goal channels (crop_goal); 4: the wide layout;
# 5: the per-type misplaced probabilities (models.decision.suspects)


def _feature_hash(demos_hash: str, perception: Path) -> str:
    digest = hashlib.sha256(f"{FEATURES_VERSION}:{demos_hash}".encode())
    digest.update(hashlib.sha256((perception / "model.pt").read_bytes()).digest())
    return digest.hexdigest()[:16]


@torch.no_grad()
def embed_split(directory: Path, perception_dir: Path, cache: Path, progress: bool = True) -> Rows:
    """Run the frozen perception over every row of a demos folder (cached by hash)."""
    from maniskill_tidy.models.checkpoints import load_perception

    manifest = json.loads((directory / "manifest.json").read_text())
    key = _feature_hash(manifest["demos_hash"], perception_dir)
    path = cache / f"features_{key}.pt"
    if path.is_file():
        saved = torch.load(path, weights_only=False)
        saved["y"]["action"] = action_labels(directory)
        return Rows(saved["x"], saved["y"], saved["index"], key)
    perception = load_perception(perception_dir)
    k = perception.cfg.categories
    shards = sorted(directory.glob("house_*.npz"))
    parts: dict[str, list] = {}
    keys: list[tuple[int, int, int]] = []
    episodes = 0
    for shard in tqdm(shards, desc=f"features {directory.parent.name} {directory.name}",
                      unit="house", disable=not progress):  # fmt: skip
        with np.load(shard) as z:
            d = {name: z[name] for name in z.files}
        n = len(d["t"])
        g = perception.cfg.crop
        for start in range(0, n, 512):
            sl = slice(start, min(start + 512, n))
            rows = np.arange(sl.start, sl.stop)
            dets = np.flatnonzero(np.isin(d["det_row"], rows))
            crop = np.unpackbits(d["crop"][sl], axis=1)[:, : g * g * (k + 2)]
            f = perception.step_features(
                torch.from_numpy(d["rgb"][sl]),
                torch.from_numpy(d["seen"][sl].astype(np.float32)),
                torch.from_numpy(crop.reshape(-1, g, g, k + 2)),
                torch.from_numpy(d["det_row"][dets] - sl.start).long(),
                torch.from_numpy(d["det_type"][dets]).long(),
                torch.from_numpy(d["det_rest"][dets]).long(),
                torch.from_numpy(d["det_numeric"][dets]),
            )
            for name in FEATURES:
                parts.setdefault(name, []).append(f[name].half())
            for name in ("mis", "det"):
                parts.setdefault(name, []).append(f[name])
            suspect = suspects(torch.from_numpy(d["det_row"][dets] - sl.start),
                               torch.from_numpy(d["det_type"][dets]), f["p_detections"],
                               sl.stop - sl.start, len(load_catalog().pickupable))  # fmt: skip
            parts.setdefault("suspect", []).append(suspect.half())
            layout = crop_layout(crop.reshape(-1, g, g, k + 2))
            parts.setdefault("layout", []).append(torch.from_numpy(layout))
            goal = crop_goal(crop.reshape(-1, g, g, k + 2))
            parts.setdefault("goal", []).append(torch.from_numpy(goal))
            parts.setdefault("wide", []).append(torch.from_numpy(d["wide"][sl]))
        parts.setdefault("pose", []).append(torch.from_numpy(d["pose"]))
        for name in ("failed", "capability", "held", *LABELS):
            parts.setdefault(name, []).append(torch.from_numpy(d[name].astype(np.int64)))
        for e, t, a in zip(d["episode"], d["t"], d["agent"], strict=True):
            keys.append((episodes + int(e), int(t), int(a)))
        episodes += len(json.loads(str(d["episodes"])))
    cat = {name: torch.cat(v) for name, v in parts.items()}
    x = {name: cat[name]
         for name in (*FEATURES, "mis", "det", "suspect", "layout", "goal", "wide")}  # fmt: skip
    x["failed"] = cat["failed"].float()
    x["pose"] = cat["pose"].float()
    x["va"] = cat["capability"].float()
    x["held"] = cat["held"]
    y = {name: cat[name] + OFFSET.get(name, 0) for name in LABELS}
    agents = max(a for _, _, a in keys) + 1
    steps = max(t for _, t, _ in keys) + 1
    index = torch.full((episodes, steps, agents), -1, dtype=torch.long)
    e, t, a = (torch.tensor(c) for c in zip(*keys, strict=True))
    index[e, t, a] = torch.arange(len(keys))
    cache.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    torch.save({"x": x, "y": y, "index": index}, buf)
    write_atomic(path, buf.getvalue())
    y["action"] = action_labels(directory)
    return Rows(x, y, index, key)


def used_input(name: str, cfg: DecisionConfig) -> bool:
    """Whether a model with ``cfg`` reads the cached input ``name`` (the goal channels are
    340 MB per 63k rows)."""
    return {"layout": cfg.layout, "goal": cfg.goal_map, "wide": cfg.wide_layout,
            "suspect": cfg.suspects}.get(name, True)  # fmt: skip


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


def action_labels(directory: Path) -> torch.Tensor:
    """The teacher's low-level action of every row of a demos folder, in the rows' order
    (w/o HierDec.'s labels; read from the shards, a few kB each)."""
    parts = []
    for shard in sorted(directory.glob("house_*.npz")):
        with np.load(shard) as z:
            parts.append(torch.from_numpy(z["action"].astype(np.int64)))
    return torch.cat(parts)


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


# ------------------------------------------------------------------- training
def _seeded(seed: int) -> None:
    torch.manual_seed(seed)
    np.random.seed(seed)


def selection_score(metrics: dict, select: str) -> float:
    """Lower is better."""
    if select == "loss":
        return metrics["loss"]
    acc, base = metrics["accuracy"], metrics["majority"]
    gains = [acc[h] - base[h] for h in acc if acc[h] is not None and base[h] is not None]
    return -float(np.mean(gains))


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
    from maniskill_tidy.common.provenance import code_version

    cfg = AgentConfig.load(config)
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
    settings = cfg.settings()
    also = [Path(root) / f"setting_{setting}" / "train" for root in cfg.also_train]
    for folder in also:
        if not (folder / "manifest.json").is_file():
            raise FileNotFoundError(f"{config}: also_train {folder} has no demonstrations; make "
                                    "them with the config that owns them first")  # fmt: skip
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
        train = train + used(embed_split(folder, perception, work, progress))
    val = used(embed_split(demos_folder(cfg, setting, "val"), perception, work, progress))
    _seeded(settings.seed)
    model = TeamDecision(decision, train.index.shape[-1])
    state = fit(model, train, val, settings, work / f"{cfg.name}.ckpt", progress)
    card = {
        "name": cfg.name,
        "setting": setting,
        "config": str(config),
        "decision": asdict(model.cfg),
        "train_settings": asdict(settings),
        "parameters_per_agent": sum(p.numel() for p in model.agents[0].parameters()),
        "agents": len(model.agents),
        "perception": str(perception),
        "demos": {
            split: {
                k: m[k]
                for k in (
                    "demos_hash",
                    "teacher",
                    "trajectories",
                    "rows",
                    "teacher_success",
                    "seconds",
                    "starts",
                    "tasks",
                    "student",
                )
                if k in m
            }
            for split, m in manifests.items()
        },  # fmt: skip
        "features": {"train": train.hash, "val": val.hash},
        "full_trajectories": _split_size(cfg.dataset, "train") * 50,
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
    folder = Path(cfg.out) / f"setting_{setting}"
    save_decision(model, folder, {"name": cfg.name, "perception": str(perception)})
    card["weights_sha256"] = weights_sha256(folder)  # checked when a team loads it
    write_atomic(folder / "card.json", json.dumps(card, indent=1, sort_keys=True).encode())
    write_atomic(folder / "MODEL_CARD.md", model_card(card).encode())
    return card


def _split_size(dataset: str, split: str) -> int:
    """Houses in a split of the dataset (for the card's time estimate)."""
    from maniskill_tidy.tasks.dataset import read_manifest

    return int(read_manifest(Path(dataset))["splits"][split])


def model_card(card: dict) -> str:
    hard, soft = card["val_inference_mode"], card["val_training_mode"]
    teacher = card["demos"]["train"].get("teacher", "expert")
    teacher = "privileged expert" if teacher == "expert" else f"camera-only {teacher}"
    lines = [
        f"# {card['name']}, Setting {card['setting']}",
        "",
        f"{_method(card['decision'])}, trained by behaviour cloning on the "
        f"{'sub-tasks and sub-goals' if card['decision'].get('hierarchical', True) else 'actions'}"
        f" of the {teacher} team (`maniskill-tidy train {card['config']} --setting "
        f"{card['setting']}`).",
        "",
        f"- agents: {card['agents']}, one model each, {card['parameters_per_agent']:,} "
        "parameters per agent, stored fp16",
        f"- perception (frozen): `{card['perception']}`",
        f"- epochs run: {card['epochs_run']}, best on val: {card['best_epoch']}; training time "
        f"{card['train_seconds']:.0f} s (2 CPU cores)",
    ]
    for split, m in card["demos"].items():
        lines.append(
            f"- {split} demonstrations: {m['trajectories']} trajectories ({m['tasks']} meta-tasks"
            f" per house x {m['starts']} start), {m['rows']} agent-steps, "
            + (
                f"played by {m['student']} and labelled by {m['teacher']} (DAgger; the "
                f"student's success {m['teacher_success']:.3f})"
                if m.get("student")
                else f"teacher {m['teacher']} (success {m['teacher_success']:.3f})"
            )
            + f", hash `{m['demos_hash'][:12]}`"
        )
    train = card["demos"]["train"]
    each = train.get("render_seconds_per_trajectory")
    if each:
        full = each * card.get("full_trajectories", 0) / 3600 / 2
        lines.append(
            f"- why this many: rendering takes {each:.0f} s per trajectory in one process; the "
            f"paper's 5 starts of all 10 meta-tasks of every train house would take {full:.0f} h"
            " with 2 processes on this machine, so the shipped model uses the first start of "
            f"the first {train['tasks']} meta-tasks per house"
        )
    if card.get("notes"):
        lines.append(f"- {card['notes']}")
    if "act" in card:
        act = ", ".join(f"{k} {v}" for k, v in card["act"].items())
        lines.append(
            f"- acting (the config's `act:` section when trained; `policies/learned.py`): {act}"
        )
    lines += [
        "",
        "Validation accuracy of every head (rows with a label), inference-mode HanGrCom "
        "(thresholded handshake) and training mode (soft):",
        "",
        "| head | inference mode | training mode | most frequent label | labelled rows |",
        "|---|---|---|---|---|",
    ]
    for head in hard["accuracy"]:
        a, b = (_fmt(m["accuracy"][head]) for m in (hard, soft))
        base = _fmt(hard.get("majority", {}).get(head))
        lines.append(f"| {head} | {a} | {b} | {base} | {hard['labelled'][head]} |")
    lines += [
        "",
        f"Validation loss: {hard['loss']:.3f} (inference), {soft['loss']:.3f} (soft).",
    ]
    if "ope_auc" in hard:
        ranked = ", ".join(f"{op} {_fmt(v)}" for op, v in hard["ope_auc"].items())
        lines.append(
            f"How well each operation's probability ranks the steps labelled with it (ROC AUC, "
            f"inference mode; 0.5 is chance): {ranked}."
        )
    lines.append("")
    return "\n".join(lines)


def _method(decision: dict) -> str:
    """What the card's model is, in words."""
    how = (
        "Hierarchical decision"
        if decision.get("hierarchical", True)
        else ("Direct low-level actions (w/o HierDec.)")
    )
    parts = [f"{how} with {scheme(decision.get('communication', 'hangrcom')).title}"]
    if not decision.get("misplaced_detector", True):
        parts.append("without the misplaced-object detector (w/o MisObjDec.)")
    if not decision.get("receptacle_predictor", True):
        parts.append("without the reasonable-receptacle predictor (w/o ReaRecPre.)")
    return ", ".join(parts)


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"
