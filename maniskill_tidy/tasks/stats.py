"""Dataset statistics of the paper's Fig. 5: share of each k, share of Single and Cross tasks."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from maniskill_tidy.common.plotting import plt, save_figure
from maniskill_tidy.tasks.dataset import SPLITS, read_manifest, read_shard


def dataset_stats(root: Path) -> dict:
    """Counts and shares of k and of Single/Cross, per split and over all splits."""
    root = Path(root)
    manifest = read_manifest(root)
    per_split: dict[str, dict[str, Counter]] = {
        s: {"k": Counter(), "kind": Counter(), "how": Counter(), "where": Counter()} for s in SPLITS
    }
    for name in sorted(manifest["files"]):
        split = name.split("/")[0]
        for t in read_shard(root / name)["tasks"]:
            per_split[split]["k"][t["k"]] += 1
            per_split[split]["kind"][t["kind"]] += 1
            for m in t["misplaced"]:
                per_split[split]["how"][m["how"]] += 1
                surface = m["misplaced"]["surface"] or ""
                per_split[split]["where"][
                    "floor"
                    if m["misplaced"]["receptacle"] == "Floor"
                    else "inside"
                    if surface.startswith(("in", "shelf", "cabinet"))
                    else "on top"
                ] += 1
    total = {
        key: sum((per_split[s][key] for s in SPLITS), Counter())
        for key in ("k", "kind", "how", "where")
    }

    def shares(c: Counter) -> dict:
        n = sum(c.values()) or 1
        return {str(k): round(v / n, 4) for k, v in sorted(c.items())}

    out = {
        "houses": manifest["houses"],
        "seed": manifest["seed"],
        "dataset_hash": manifest["dataset_hash"],
        "splits": {},
    }
    for name, counters in [*per_split.items(), ("all", total)]:
        out["splits"][name] = {
            "tasks": sum(counters["k"].values()),
            "k_share": shares(counters["k"]),
            "kind_share": shares(counters["kind"]),
            "move_share": shares(counters["how"]),
            "where_share": shares(counters["where"]),
        }
    return out


def format_stats(stats: dict) -> str:
    lines = [
        f"dataset {stats['dataset_hash'][:12]}: {stats['houses']} houses, seed {stats['seed']}",
        f"{'split':<6} {'tasks':>6}  "
        + "  ".join(f"k={k}" for k in range(1, 6))
        + "   Single   Cross",
    ]
    for split, s in stats["splits"].items():
        ks = "  ".join(f"{s['k_share'].get(str(k), 0):.2f}" for k in range(1, 6))
        lines.append(
            f"{split:<6} {s['tasks']:>6}  {ks}   {s['kind_share'].get('Single', 0):.3f}"
            f"   {s['kind_share'].get('Cross', 0):.3f}"
        )
    where = stats["splits"]["all"]["where_share"]
    lines.append(
        "misplaced objects lie: "
        + ", ".join(f"{k} {v:.2f}" for k, v in sorted(where.items()))
        + " (inside: shelves and compartments, whose doors the env opens)"
    )
    return "\n".join(lines)


def plot_stats(stats: dict, out: Path) -> Path:
    s = stats["splits"]["all"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3.6))
    ks = [str(k) for k in range(1, 6)]
    a.pie(
        [s["k_share"].get(k, 0) for k in ks],
        labels=[f"k={k}" for k in ks],
        autopct="%1.1f%%",
        startangle=90,
        counterclock=False,
    )
    a.set_title("(a) number of misplaced objects")
    kinds = ["Single", "Cross"]
    b.pie(
        [s["kind_share"].get(k, 0) for k in kinds],
        labels=kinds,
        autopct="%1.1f%%",
        startangle=90,
        counterclock=False,
        colors=["#90caf9", "#ffab91"],
    )
    b.set_title("(b) Single-Room vs Cross-Room tasks")
    fig.suptitle(
        f"{s['tasks']} meta-tasks in {stats['houses']} houses "
        f"(dataset {stats['dataset_hash'][:12]})",
        fontsize=9,
    )
    return save_figure(fig, out, dpi=120)
