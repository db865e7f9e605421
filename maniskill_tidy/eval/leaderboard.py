"""``eval/LEADERBOARD.md``: every run's summary in the layout of the paper's Tables 3 and 4.

Rows are methods, columns Success, %PS, %FM, #PL, ACm and CES for Single / Cross / All. Our rows
come from ``eval/results/setting_*/<policy>/summary.json``; the paper's own figures (measured in
AI2-THOR/ProcTHOR with learned models, so not directly comparable) follow as reference rows.
CES needs the single-agent baseline's success in the same setting and split: our ``sa`` run for
our rows, the paper's SA row for the paper's.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from maniskill_tidy.eval.metrics import SPLITS, ces

COLUMNS = ("Success", "%PS", "%FM", "#PL", "ACm", "CES")
ORDER = (
    "sa",
    "random",
    "heuristic-none",
    "heuristic-detection",
    "heuristic-broadcast",
    "heuristic-central",
    "expert",
)


def paper_reference() -> dict:
    text = resources.files("maniskill_tidy.eval").joinpath("paper_reference.json").read_text()
    return json.loads(text)


def collect(root: Path) -> dict[str, dict[str, dict]]:
    """setting -> policy -> summary, for every summary.json under ``root``/results."""
    out: dict[str, dict[str, dict]] = {}
    for path in sorted(Path(root).glob("results/setting_*/*/summary.json")):
        summary = json.loads(path.read_text())
        out.setdefault(summary["setting"], {})[summary["policy"]] = summary
    return out


def _fmt(v, column: str) -> str:
    if v is None:
        return "-"
    return f"{v:.1f}" if column in ("#PL", "ACm", "CES") else f"{v:.3f}"


def _our_row(summary: dict, sa: dict | None) -> list[str]:
    cells = []
    for column in COLUMNS:
        for split in SPLITS:
            m = summary["metrics"][split]
            if column == "CES":
                v = None
                if sa is not None and m["ACm"] and summary["policy"] != "sa":
                    v = ces(m["Success"], sa["metrics"][split]["Success"] or 0.0, m["ACm"])
            elif column == "ACm" and summary["policy"] == "sa":
                v = None  # one agent: nobody to talk to
            else:
                v = m[column]
            cells.append(_fmt(v, column))
    return cells


def table(setting: str, runs: dict[str, dict], reference: dict) -> str:
    head = "| Method | " + " | ".join(f"{c} {s}" for c in COLUMNS for s in SPLITS) + " |"
    lines = [head, "|---" * (1 + len(COLUMNS) * len(SPLITS)) + "|"]
    sa = runs.get("sa")
    for policy in sorted(runs, key=lambda p: (ORDER.index(p) if p in ORDER else 99, p)):
        s = runs[policy]
        tag = " (privileged)" if s.get("privileged") else ""
        lines.append(f"| **{policy}**{tag} | " + " | ".join(_our_row(s, sa)) + " |")
    for name, values in reference["rows"].get(setting, {}).items():
        cells = [_fmt(v, COLUMNS[i // 3]) for i, v in enumerate(values)]
        lines.append(f"| {name} *(paper)* | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def details(runs: dict[str, dict]) -> str:
    lines = [
        "| Method | team | communication | perception | episodes | dataset | code | s/episode |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for policy, s in sorted(runs.items()):
        lines.append(
            f"| {policy} | {s['team']} | {s['communication']} | {s['perception'] or '-'} | "
            f"{s['episodes']} | {s['dataset_hash'][:12]} | {s['code_version']} | "
            f"{s['episode_seconds_mean']} |"
        )
    return "\n".join(lines)


def plot(runs_by_setting: dict[str, dict[str, dict]], reference: dict, out: Path) -> Path:
    import matplotlib.pyplot as plt

    from maniskill_tidy.plotting import save_figure

    settings = sorted(runs_by_setting) or ["I"]
    fig, axes = plt.subplots(1, len(settings), figsize=(6 * len(settings), 4.2), squeeze=False)
    cols = reference["columns"]
    for ax, setting in zip(axes[0], settings, strict=True):
        for policy, s in runs_by_setting.get(setting, {}).items():
            m = s["metrics"]["All"]
            ax.scatter(m["ACm"], m["Success"], s=60, zorder=3)
            ax.annotate(
                policy,
                (m["ACm"], m["Success"]),
                textcoords="offset points",
                xytext=(5, 4),
                fontsize=8,
            )
        for name, values in reference["rows"].get(setting, {}).items():
            acm, suc = values[cols.index("ACm All")], values[cols.index("Success All")]
            if acm is None:
                continue
            ax.scatter(acm, suc, s=40, facecolors="none", edgecolors="grey", zorder=2)
            ax.annotate(
                f"{name} (paper)",
                (acm, suc),
                textcoords="offset points",
                xytext=(5, -9),
                fontsize=7,
                color="grey",
            )
        ax.set(
            xlabel="ACm: values received per agent per step",
            ylabel="Success (All)",
            title=f"Setting {setting}: success against communication",
        )
        ax.grid(alpha=0.3)
    return save_figure(fig, out)


def write_leaderboard(root: Path = Path("eval")) -> Path:
    from maniskill_tidy.tasks.dataset import write_atomic

    root = Path(root)
    runs = collect(root)
    reference = paper_reference()
    parts = [
        "# Leaderboard",
        "",
        "Written by `maniskill-tidy leaderboard` from the run summaries under "
        "`eval/results/`; each row comes from `maniskill-tidy eval --policy NAME --setting S "
        "--split test --dataset DIR` (see the details table). Rows marked *(paper)* are the "
        "figures the paper reports (AI2-THOR/ProcTHOR, learned models): reference points, not "
        "runs of this code. *(privileged)* rows read the simulator state. Non-privileged teams "
        "here use ground-truth instance segmentation in place of a trained detector.",
        "",
        "![success against communication](leaderboard.png)",
        "",
    ]
    for setting in sorted(set(runs) | set(reference["rows"])):
        parts += [f"## Setting {setting}", "", table(setting, runs.get(setting, {}), reference), ""]
        if runs.get(setting):
            parts += ["Runs:", "", details(runs[setting]), ""]
    out = root / "LEADERBOARD.md"
    write_atomic(out, "\n".join(parts).encode())
    plot(runs, reference, root / "leaderboard.png")
    return out
