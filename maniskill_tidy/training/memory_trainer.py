"""Behaviour cloning of the object-memory team's pointer on its teacher's choices.

``maniskill-tidy train agents/memory.yaml --setting S``: records the teacher's choices on the
train and val houses (``training/memory_data.py``, resumable), fits the pointer
(``models/memory_pointer.py``) with cross-entropy over each decision's candidates (each row
weighted by how rare its kind of choice is), keeps the epoch of best balanced val accuracy,
then plays the first ``val_episodes`` val episodes with the trained team and with its teacher
(``eval`` runs under the work folder) for the card. Training resumes from its last epoch (an
atomic checkpoint per epoch).
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
from torch import nn
from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.checkpoints import save_memory, type_vectors, weights_sha256
from maniskill_tidy.models.memory_pointer import MemoryPointer
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.memory_candidates import CONTEXT, KINDS, numeric_width
from maniskill_tidy.tasks.teams import SETTINGS
from maniskill_tidy.training.memory_data import build_memory_data, load_memory_rows

INPUTS = ("kind", "type", "rest", "numeric", "context")


def tensors(rows: dict[str, np.ndarray]) -> dict[str, torch.Tensor]:
    return {k: torch.from_numpy(np.ascontiguousarray(rows[k])) for k in (*INPUTS, "label")}


def chosen_kind(data: dict[str, torch.Tensor]) -> torch.Tensor:
    """The kind of job the teacher chose, per row."""
    return data["kind"].gather(1, data["label"].long()[:, None])[:, 0].long()


def kind_weights(data: dict[str, torch.Tensor]) -> torch.Tensor:
    """Per row, 1 / (how often the teacher chose that kind), averaging 1 over the rows: most
    choices are "explore the next cell", and the few that fetch or place are what tidies."""
    kinds = chosen_kind(data)
    counts = torch.bincount(kinds, minlength=len(KINDS)).float()
    w = 1.0 / counts[kinds]
    return w * len(w) / w.sum()


def accuracy(model: MemoryPointer, data: dict[str, torch.Tensor]) -> dict:
    """Val loss, accuracy, accuracy by the kind of job the teacher chose, and their mean
    (``balanced``, what selects the epoch)."""
    with torch.no_grad():
        logits = model(*(data[k] for k in INPUTS))
        loss = nn.functional.cross_entropy(logits, data["label"].long()).item()
    right = logits.argmax(-1) == data["label"]
    chosen = chosen_kind(data)
    by_kind = {KINDS[k]: round(float(right[chosen == k].float().mean()), 4)
               for k in range(len(KINDS)) if (chosen == k).any()}  # fmt: skip
    return {"loss": round(loss, 4), "accuracy": round(float(right.float().mean()), 4),
            "balanced": round(float(np.mean(list(by_kind.values()))), 4),
            "by_kind": by_kind}  # fmt: skip


def train_memory(config: Path, setting: str, progress: bool = True) -> dict:
    """Record, train (resumable), validate; write the model, its card and curve; the card."""
    if setting not in SETTINGS:
        raise ValueError(f"unknown setting {setting!r}; expected one of {sorted(SETTINGS)}")
    cfg = MemoryConfig.load(config)
    if cfg.links:  # a trained pointer, learned links carrying memory entries
        from maniskill_tidy.training.memory_links import train_links

        return train_links(cfg, config, setting, progress)
    s = cfg.settings()
    train_dir = build_memory_data(config, setting, "train", progress)
    val_dir = build_memory_data(config, setting, "val", progress)
    train, val = tensors(load_memory_rows(train_dir)), tensors(load_memory_rows(val_dir))
    manifests = {split: json.loads((d / "manifest.json").read_text())
                 for split, d in (("train", train_dir), ("val", val_dir))}  # fmt: skip
    torch.manual_seed(s["seed"])
    sizes = {"kinds": len(KINDS), "receptacles": len(load_catalog().receptacles),
             "numeric": numeric_width(cfg.explore), "context": len(CONTEXT),
             **cfg.model}  # fmt: skip
    model = MemoryPointer(type_vectors(), **sizes)
    optimiser = torch.optim.Adam(model.parameters(), lr=s["lr"])
    key = json.dumps({"settings": s, "sizes": sizes,
                      "data": [m["data_hash"] for m in manifests.values()]})  # fmt: skip
    ckpt = Path(cfg.work) / f"setting_{setting}" / "pointer.ckpt"
    state = {"epoch": 0, "curve": [], "seconds": 0.0, "best": None, "best_epoch": 0}
    best_state = copy.deepcopy(model.state_dict())
    if ckpt.is_file():
        saved = torch.load(ckpt, weights_only=False)
        if saved["key"] == key:
            model.load_state_dict(saved["model"])
            optimiser.load_state_dict(saved["optimiser"])
            torch.set_rng_state(saved["torch_rng"])
            state, best_state = saved["state"], saved["best_state"]
    n = len(train["label"])
    weights = kind_weights(train)
    bar = tqdm(total=s["epochs"], initial=state["epoch"], desc=f"memory pointer {setting}",
               unit="epoch", disable=not progress)  # fmt: skip
    with bar:
        while state["epoch"] < s["epochs"] and state["epoch"] - state["best_epoch"] < s["patience"]:
            started = time.perf_counter()
            model.train()
            losses = []
            for idx in torch.randperm(n).split(s["batch"]):
                logits = model(*(train[k][idx] for k in INPUTS))
                each = nn.functional.cross_entropy(
                    logits, train["label"][idx].long(), reduction="none"
                )
                loss = (each * weights[idx]).mean()
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                losses.append(loss.item())
            model.eval()
            v = accuracy(model, val)
            state["epoch"] += 1
            state["seconds"] += time.perf_counter() - started
            point = {"epoch": state["epoch"], "train_loss": float(np.mean(losses)),
                     "val_loss": v["loss"], "val_accuracy": v["accuracy"],
                     "val_balanced": v["balanced"]}  # fmt: skip
            state["curve"].append(point)
            if state["best"] is None or v["balanced"] > state["best"]["balanced"]:
                state["best"], state["best_epoch"] = v, state["epoch"]
                best_state = copy.deepcopy(model.state_dict())
            buf = io.BytesIO()
            torch.save({"key": key, "model": model.state_dict(),
                        "optimiser": optimiser.state_dict(), "torch_rng": torch.get_rng_state(),
                        "state": state, "best_state": best_state}, buf)  # fmt: skip
            write_atomic(ckpt, buf.getvalue())
            bar.update(1)
            bar.set_postfix(val_balanced=f"{v['balanced']:.3f}")
    model.load_state_dict(best_state)
    model.eval()
    reinforced = {}
    if cfg.reinforce:
        from maniskill_tidy.training.memory_reinforce import reinforce_pointer

        model, reinforced = reinforce_pointer(cfg, config, setting, model, sizes, progress)
    forked = {}
    if cfg.forks:
        from maniskill_tidy.training.memory_forks import improve_pointer

        model, forked = improve_pointer(cfg, config, setting, model, sizes, progress)
    folder = Path(cfg.out) / f"setting_{setting}"
    extra = {"name": cfg.name, "teacher": cfg.teacher}
    if cfg.explore > 1:  # pointers trained before the option had one explore candidate
        extra["explore"] = cfg.explore
    save_memory(model, folder, sizes, extra)
    card = {
        "name": cfg.name, "setting": setting, "config": str(config), "settings": asdict(cfg),
        "train": s, "data": manifests, "epochs": state["epoch"], "best_epoch": state["best_epoch"],
        "train_seconds": round(state["seconds"], 1), "curve": state["curve"],
        "val": state["best"], "parameters": sum(p.numel() for p in model.parameters()),
        "weights_sha256": weights_sha256(folder),
    }  # fmt: skip
    if reinforced:
        card["reinforce"] = reinforced
    if forked:
        card["forks"] = forked
    # the card's hash first: the closed-loop runs below load the weights through it
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    card["closed_loop"] = closed_loop(cfg, config, setting, progress)
    from maniskill_tidy.common.provenance import code_version

    card["code_version"] = code_version()
    write_atomic(folder / "card.json", json.dumps(card, indent=1).encode())
    write_atomic(folder / "MODEL_CARD.md", memory_card(card).encode())
    plot_curve(card, folder / "curve.png")
    if reinforced:
        from maniskill_tidy.training.memory_reinforce import plot_reinforce

        plot_reinforce(card, folder / "reinforce.png")
    if forked:
        from maniskill_tidy.training.memory_forks import plot_forks

        plot_forks(card, folder / "forks.png")
    return card


def closed_loop(cfg: MemoryConfig, config: Path, setting: str, progress: bool) -> dict:
    """The first ``val_episodes`` val episodes played by the trained team and its teacher."""
    from maniskill_tidy.eval.runner import RunConfig, evaluate
    from maniskill_tidy.policies import team_class

    if cfg.val_episodes < 1:
        return {}
    out = {}
    for who, policy in (("student", str(config)), ("teacher", cfg.teacher)):
        run = RunConfig(policy, setting, "val", cfg.dataset, episodes=cfg.val_episodes,
                        env=cfg.env)  # fmt: skip
        team = team_class(policy)
        where = Path(cfg.work) / f"setting_{setting}" / "closed_loop" / who
        if team.rules:  # a run under other rules is a new run, not a resumed one
            where = where / team.rules
        if who == "student":  # and so is a retrained pointer's
            where = where / team.model_hash(SETTINGS[setting])
        summary = evaluate(run, where, workers=cfg.workers, progress=progress)
        m = summary["metrics"]["All"]
        out[who] = {k: m[k] for k in ("Success", "%PS", "%FM", "#PL", "ACm")}
        out[who]["episodes"] = summary["episodes"]
    return out


def memory_card(card: dict) -> str:
    s, val, data = card["train"], card["val"], card["data"]
    lines = [
        f"# {card['name']}, Setting {card['setting']}",
        "",
        "The object-memory team's pointer over the jobs an agent could take next, trained by "
        f"behaviour cloning on `{card['settings']['teacher']}`'s own choices "
        f"(`maniskill-tidy train {card['config']} --setting {card['setting']}`). Stand-ins: "
        "ground-truth segmentation for detections, D for misplaced.",
        "",
        f"- data: {data['train']['rows']} train decisions from {data['train']['trajectories']} "
        f"teacher episodes (teacher success {data['train']['teacher_success']:.3f}), "
        f"{data['val']['rows']} val decisions from {data['val']['trajectories']}; data hashes "
        f"{data['train']['data_hash'][:12]} / {data['val']['data_hash'][:12]}; recording took "
        f"{data['train']['seconds'] + data['val']['seconds']:.0f} s on 2 cores",
        f"- training: Adam lr {s['lr']}, batches of {s['batch']} decisions, "
        f"each weighted by 1 / how often the teacher chose its kind, {card['epochs']} epochs "
        f"({card['train_seconds']:.0f} s), best balanced val accuracy at epoch "
        f"{card['best_epoch']}; {card['parameters']:,} parameters",
        f"- val (teacher's choices): accuracy {val['accuracy']:.3f}, balanced (the mean over "
        f"kinds) {val['balanced']:.3f}, loss {val['loss']:.3f}; by the teacher's kind of job: "
        + ", ".join(f"{k} {v:.3f}" for k, v in val["by_kind"].items()),
    ]
    if "reinforce" in card:
        r = card["reinforce"]
        cloned, best = r["cloned_val"], r["best"]
        lines.append(
            f"- then PPO on the team's return at job boundaries: {r['rounds']} rounds of "
            f"{r['settings']['episodes']} sampled train episodes ({r['seconds']:.0f} s), KL "
            f"weight {r['settings']['kl']} towards the cloned pointer; on the first "
            f"{cloned['episodes']} val episodes (best choices), the cloned pointer put "
            f"{cloned['placed']:.3f} of the objects where they belong (Success "
            f"{cloned['success']:.3f}); kept: round {best['round']}, {best['placed']:.3f} "
            f"(Success {best['success']:.3f}). ![PPO](reinforce.png)"
        )
    if "forks" in card:
        fk, s = card["forks"], card["forks"]["settings"]
        gain = fk["val_gain"]["placed"]
        changed = sum(c["fork_better"] + c["fork_worse"] for c in fk["curve"])
        lines.append(
            f"- then policy improvement from forked episodes: {fk['rounds']} rounds of "
            f"{s['episodes']} train episodes with the best choices and {s['forks']} forks each "
            f"({fk['forks_played']} forks, {changed} of which changed the team's return; "
            f"{fk['seconds']:.0f} s"
            + (f", then {fk['val_seconds']:.0f} s of val" if fk.get("val_seconds") else "")
            + f"), KL weight {s['kl']} towards the "
            f"cloned pointer; on {fk['val_gain']['episodes']} val episodes the last round put "
            f"{fk['val']['last']['placed']:.3f} of the objects where they belong against the "
            f"clone's {fk['val']['cloned']['placed']:.3f} (paired {gain['difference']:+.4f}, "
            f"95 % interval [{gain['ci95'][0]:+.4f}, {gain['ci95'][1]:+.4f}]); kept: the "
            f"{fk['kept']} pointer. ![forks](forks.png)"
        )
    for who, m in card.get("closed_loop", {}).items():
        lines.append(
            f"- closed loop, {m['episodes']} val episodes, {who}: Success {m['Success']:.3f}, "
            f"%PS {m['%PS']:.3f}, %FM {m['%FM']:.3f}, #PL {m['#PL']:.1f}, ACm {m['ACm']:.1f}"
        )
    lines += ["", "![learning curve](curve.png)", ""]
    return "\n".join(lines)


def plot_curve(card: dict, out: Path) -> Path:
    import matplotlib.pyplot as plt

    from maniskill_tidy.common.plotting import save_figure

    curve = card["curve"]
    epochs = [c["epoch"] for c in curve]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3))
    a.plot(epochs, [c["train_loss"] for c in curve], label="train (weighted by kind)")
    a.plot(epochs, [c["val_loss"] for c in curve], label="val")
    a.set(xlabel="epoch", ylabel="cross-entropy", title="loss")
    a.legend()
    b.plot(epochs, [c["val_accuracy"] for c in curve], label="all choices")
    b.plot(epochs, [c["val_balanced"] for c in curve], label="mean over kinds")
    b.axvline(card["best_epoch"], color="grey", ls=":")
    b.set(xlabel="epoch", ylabel="accuracy", title="val: the teacher's choice")
    b.legend()
    fig.suptitle(f"{card['name']}, Setting {card['setting']}")
    return save_figure(fig, out, dpi=100)
