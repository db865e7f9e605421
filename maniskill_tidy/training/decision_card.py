"""The model card written next to a trained decision model (markdown, from its card.json)."""

from __future__ import annotations

from pathlib import Path

from maniskill_tidy.models.communication import scheme


def split_size(dataset: str, split: str) -> int:
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
