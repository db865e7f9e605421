"""``eval/LEADERBOARD.md``: every run's summary in the layout of the paper's Tables 3-6.

Per setting a table of methods (Tables 3-4) and one of ablations (Tables 5-6); rows are methods,
columns Success, %PS, %FM, #PL, ACm and CES for Single / Cross / All. Our rows
come from ``eval/results/setting_*/<policy>/summary.json``; the paper's own figures (measured in
AI2-THOR/ProcTHOR with learned models, so not directly comparable) follow as reference rows.
CES needs the single-agent baseline's success in the same setting and split: our learned SA
(``sa-learned``) for our learned rows, our heuristic ``sa`` for the heuristic rows, the paper's
SA row for the paper's. A plot puts Success against ACm, with the Pareto fronts of our rows
and of our learned rows alone.
Our Success cells carry their 95 % bootstrap interval; a run whose episodes were played by more
than one code version is flagged, and so is one played under a team's earlier rules
(``Team.rules``). Runs of the paper's full protocol (``eval ... --episodes all
--out eval/all``: every start, 1000 episodes) get a table of their own under each setting, so a
method can have both its standard row and its full one.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from maniskill_tidy.eval.metrics import SPLITS, EpisodeRecord, ces, paired_difference

COLUMNS = ("Success", "%PS", "%FM", "#PL", "ACm", "CES")
# policies whose team_override fixes the team
SAME_IN_EVERY_SETTING = ("sa", "sa-learned", "sa-oracle")
ORDER = (
    "sa",
    "sa-learned",
    "sa-oracle",
    "random",
    "qmix",
    "heuristic-none",
    "heuristic-detection",
    "heuristic-broadcast",
    "heuristic-central",
    "memory",  # beyond the paper: heuristic memory, a learned choice of job
    "wo_know",
    "wo_misobjdec",
    "wo_rearecpre",
    "wo_comm",
    "wo_hierdec",
    "condcomm",
    "cmprcomm",
    "intencomm",
    "hangrcom",
    "broadcomm",
    "centralcomm",
    "expert",
)
ABLATIONS = {
    "wo_know": "Ours w/o Know.",
    "wo_misobjdec": "Ours w/o MisObjDec.",
    "wo_rearecpre": "Ours w/o ReaRecPre.",
    "wo_comm": "Ours w/o Comm.",
    "wo_hierdec": "Ours w/o HierDec.",
}
# Our learned rows and the paper's row of the same method, shown one under the other.
PAPER_ROW = {
    "hangrcom": "Ours",
    "sa-learned": "SA",
    "sa-oracle": "SA(Oracle)",
    "qmix": "QMIX",
    "condcomm": "CondComm.",
    "cmprcomm": "CmprComm.",
    "intencomm": "IntenComm.",
    "broadcomm": "BroadComm.",
    "centralcomm": "CentralComm.",
    **ABLATIONS,
}


def paper_reference() -> dict:
    text = resources.files("maniskill_tidy.eval").joinpath("paper_reference.json").read_text()
    return json.loads(text)


def collect(root: Path) -> dict[str, dict[str, dict]]:
    """setting -> policy -> summary, for every summary.json under ``root``/results.

    A team that plays with its own team whatever the setting (SA: one manipulator, starting
    where Setting I's first agent does) plays the same episodes in every setting; its run in
    one setting stands for the others that lack one, marked so."""
    out: dict[str, dict[str, dict]] = {}
    for path in sorted(Path(root).glob("results/setting_*/*/summary.json")):
        summary = json.loads(path.read_text())
        today = rules_today(path.parent)
        if today is not None and today != summary.get("rules", ""):
            summary["rules_today"] = today
        out.setdefault(summary["setting"], {})[summary["policy"]] = summary
    for setting, runs in out.items():
        for other, other_runs in out.items():
            for policy, s in other_runs.items():
                same_everywhere = policy in SAME_IN_EVERY_SETTING and "shared_from" not in s
                if same_everywhere and policy not in runs and other != setting:
                    runs[policy] = {**s, "setting": setting, "shared_from": other}
    return out


def rules_today(run: Path) -> str | None:
    """Today's ``Team.rules`` of the team a run played (its ``run.json``'s policy argument), or
    None where that team is not known here (a config since removed)."""
    from maniskill_tidy.policies import team_class

    try:
        policy = json.loads((run / "run.json").read_text())["policy"]
        return getattr(team_class(policy), "rules", "")
    except Exception:  # a folder or config this checkout cannot read: nothing to compare
        return None


def episodes(root: Path, setting: str, runs: dict[str, dict]) -> dict[str, list[EpisodeRecord]]:
    """policy -> the finished episodes of its run (a run shared from another setting reads that
    setting's), for the paired comparisons of ``orderings``."""
    from maniskill_tidy.eval.runner import read_records

    out = {}
    for policy, s in runs.items():
        folder = Path(root) / "results" / f"setting_{s.get('shared_from', setting)}" / policy
        if records := read_records(folder / "episodes.jsonl", repair=False):
            out[policy] = records
    return out


# Where our count differs from the paper's, said next to the figure.
ACM_NOTES = {
    "heuristic-central": "ACm counts the uploads to the central node and the assignments it "
    "sends back (410 + 6 values per agent and step); the paper gives CentralComm. the broadcast "
    "figure (820 in Setting I, 1230 in II).",
    "centralcomm": "ACm counts the uploads to the central node and the assignments it sends "
    "back (410 + 64 values per agent and step); the paper gives CentralComm. the broadcast "
    "figure (820 in Setting I, 1230 in II).",
}


def _fmt(v, column: str) -> str:
    if v is None:
        return "-"
    return f"{v:.1f}" if column in ("#PL", "ACm", "CES") else f"{v:.3f}"


def _interval(m: dict, column: str) -> str:
    ci = (m.get("ci95") or {}).get(column)
    return f" [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else ""


def learned(summary: dict) -> bool:
    return str(summary.get("perception", "")).startswith("learned")


def learned_row(summary: dict) -> bool:
    """A row of a learned team: learned perception, or weights of its own (the object-memory
    team's pointer reads ground-truth segmentation)."""
    return learned(summary) or bool(summary.get("model_hash"))


def sa_baseline(summary: dict, runs: dict[str, dict]) -> dict | None:
    """The SA run a row's CES is measured against: learned rows against the learned SA."""
    return runs.get("sa-learned") if learned(summary) else runs.get("sa")


def _our_row(summary: dict, sa: dict | None) -> list[str]:
    cells = []
    for column in COLUMNS:
        for split in SPLITS:
            m = summary["metrics"][split]
            if column == "CES":
                v = None
                if sa is not None and m["ACm"] and summary["policy"] != sa["policy"]:
                    v = ces(m["Success"], sa["metrics"][split]["Success"] or 0.0, m["ACm"])
            elif column == "ACm" and summary["policy"] in SAME_IN_EVERY_SETTING:
                v = None  # one agent: nobody to talk to
            else:
                v = m[column]
            cell = _fmt(v, column)
            if column == "Success" and v is not None:
                cell += _interval(m, column)
            if column == "ACm" and summary["policy"] in ACM_NOTES and v is not None:
                cell += " †"
            cells.append(cell)
    return cells


def row_order(policy: str) -> tuple:
    """The paper's order; a run on another env version (``expert-v2``) right after its v1."""
    base, _, version = policy.rpartition("-v")
    if not (base and version.isdigit()):
        base, version = policy, ""
    return (ORDER.index(base) if base in ORDER else 99, base, version)


def table(setting: str, runs: dict[str, dict], reference: dict, kind: str = "rows") -> str:
    """Our runs of one kind (``rows``: methods, ``ablations``) in one setting, each learned row
    followed by the paper's row of the same method, then the paper's rows left over."""
    head = "| Method | " + " | ".join(f"{c} {s}" for c in COLUMNS for s in SPLITS) + " |"
    lines = [head, "|---" * (1 + len(COLUMNS) * len(SPLITS)) + "|"]
    notes = []
    # the ablations' table also shows the full model, as the paper's does
    mine = {p: s for p, s in runs.items() if (p in ABLATIONS) == (kind == "ablations")}
    if kind == "ablations" and "hangrcom" in runs:
        mine["hangrcom"] = runs["hangrcom"]
    for policy in sorted(mine, key=row_order):
        s = runs[policy]
        tag = " (privileged)" if s.get("privileged") else ""
        if s.get("env", "HeteroTidy-v1") != "HeteroTidy-v1":
            tag += f" ({s['env']}: the realistic look, same episodes)"
        if s.get("shared_from"):
            tag += f" (the Setting {s['shared_from']} run: the same team and episodes)"
        if len(s.get("code_versions", [])) > 1:
            tag += " ‡"
            notes.append(f"‡ {policy}: episodes played by code versions {s['code_versions']}.")
        if "rules_today" in s:
            tag += " ¶"
            notes.append(
                f"¶ {policy}: played under the team's rules {s.get('rules') or 'as first played'!r}"
                f", not today's {s['rules_today']!r}: re-run it to compare it with today's rows."
            )
        if policy in ACM_NOTES:
            notes.append(f"† {policy}: {ACM_NOTES[policy]}")
        row = _our_row(s, sa_baseline(s, runs))
        lines.append(f"| **{policy}**{tag} | " + " | ".join(row) + " |")
        if policy in PAPER_ROW and PAPER_ROW[policy] in reference.get(kind, {}).get(setting, {}):
            lines.append(_paper_row(PAPER_ROW[policy], reference, setting, kind, notes))
    paired = {PAPER_ROW[p] for p in mine if p in PAPER_ROW}
    for name in reference.get(kind, {}).get(setting, {}):
        if name not in paired:
            lines.append(_paper_row(name, reference, setting, kind, notes))
    if notes:
        lines += [""] + [f"{n}  " for n in notes]
    return "\n".join(lines)


def from_pixels(summary: dict) -> bool:
    """A pixels-track run (``eval --segmentation``): its own table, never among the rows that
    read the renderer's segmentation."""
    return summary.get("segmentation", "ground-truth") != "ground-truth"


def ground_truth_partner(policy: str) -> str:
    """The same team in the same look on the renderer's segmentation: ``memory-v2-pixels`` and
    ``memory-v2-pixels-segmenter-v1`` pair with ``memory-v2``."""
    return policy.split("-pixels", 1)[0]


def shipped_segmenter(policy: str, look: str) -> str | None:
    """The sha256 agents record for the segmenter a pixels row names, as it ships now (None
    where its folder is not there): a row whose agents ran other weights is to be played
    again, and its table says so."""
    from maniskill_tidy.eval.runner import row_segmenter
    from maniskill_tidy.models.checkpoints import CheckpointError, served_sha256

    try:
        return served_sha256(row_segmenter(policy, look))
    except (CheckpointError, OSError):
        return None


def pixels_table(runs: dict[str, dict], played: dict[str, list[EpisodeRecord]]) -> str:
    """Each pixels run beside its team on ground truth in the same look: Success, and the
    paired difference over the episodes both played."""
    from maniskill_tidy.eval.metrics import paired_difference
    from maniskill_tidy.eval.runner import row_segmenter
    from maniskill_tidy.policies.pixels import PIXELS_PIPELINE

    lines = ["| Team | look | segmenter | Success (pixels) | Success (ground truth) | "
             "pixels - ground truth (paired) | kept | %FM (pixels / ground truth) |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for policy in sorted((p for p, s in runs.items() if from_pixels(s)), key=row_order):
        s = runs[policy]
        partner = ground_truth_partner(policy)
        look = s.get("env", "HeteroTidy-v1")
        weights = s["segmentation"].split(":", 1)[-1]
        shipped = shipped_segmenter(policy, look)
        trained = row_segmenter(policy, look).name
        trained = "its own look's" if trained == f"segmenter-{look.rsplit('-', 1)[1]}" else trained
        stale = "; not the one that ships" if shipped not in (None, weights) else ""
        if s.get("pixels_pipeline", "") != PIXELS_PIPELINE:  # its agents read labels otherwise
            stale += f"; before the {PIXELS_PIPELINE!r} pipeline"
        m = s["metrics"]["All"]
        cells = [f"**{policy}**", look, f"{trained} ({weights[:12]}{stale})",
                 f"{m['Success']:.3f}{_interval(m, 'Success')}"]  # fmt: skip
        g = runs.get(partner)
        if g is None or policy not in played or partner not in played:
            cells += [f"- (no {partner} run)", "-", "-", "-"]
        else:
            gm = g["metrics"]["All"]
            d = paired_difference(played[policy], played[partner])["Success"]
            lo, hi = d["ci95"]
            kept = m["Success"] / gm["Success"] if gm["Success"] else None
            cells += [f"{gm['Success']:.3f}", f"{d['difference']:+.3f} [{lo:+.3f}, {hi:+.3f}]",
                      "-" if kept is None else f"{kept:.2f}",
                      f"{m['%FM']:.3f} / {gm['%FM']:.3f}"]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def misprints(values: list[float | None]) -> list[str]:
    """The columns of a paper row whose All lies outside its Single and Cross: All averages
    over the Single and Cross episodes, so one of the three printed figures is wrong."""
    out = []
    for i, column in enumerate(COLUMNS):
        if column == "CES":  # a ratio of Success gains: not an average over episodes
            continue
        single, cross, both = values[3 * i : 3 * i + 3]
        if None in (single, cross, both):
            continue
        slack = 0.2 if column in ("#PL", "ACm") else 0.002  # the printed rounding
        if not min(single, cross) - slack <= both <= max(single, cross) + slack:
            out.append(column)
    return out


def _paper_row(
    name: str, reference: dict, setting: str, kind: str = "rows", notes: list | None = None
) -> str:
    values = reference[kind][setting][name]
    cells = [_fmt(v, COLUMNS[i // 3]) for i, v in enumerate(values)]
    for column in misprints(values):
        i = 3 * COLUMNS.index(column)
        cells[i + 2] += " §"
        if notes is not None:
            notes.append(
                f"§ {name} (paper): {column} Single {values[i]}, Cross {values[i + 1]}, All "
                f"{values[i + 2]}, as printed; All averages the Single and Cross episodes, so "
                "one of the three is a misprint."
            )
    return f"| {name} *(paper)* | " + " | ".join(cells) + " |"


def details(runs: dict[str, dict]) -> str:
    lines = [
        "| Method | team | communication | perception | protocol | episodes | dataset | weights "
        "| code | s/episode |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for policy, s in sorted(runs.items()):
        code = ", ".join(s.get("code_versions") or [s["code_version"]])
        if len(s.get("code_versions") or []) > 1:
            code += " (mixed)"
        lines.append(
            f"| {policy} | {s['team']} | {s['communication']} | {s['perception'] or '-'} | "
            f"{s.get('protocol', '-')} | {s['episodes']} | {s['dataset_hash'][:12]} | "
            f"{s.get('model_hash') or '-'} | {code} | "
            f"{s['episode_seconds_mean']} |"
        )
    return "\n".join(lines)


def pareto_front(runs: dict[str, dict], learned_only: bool = False) -> list[tuple[float, float]]:
    """(ACm, Success) of the runs no other run beats on both (less ACm, more Success), by
    increasing ACm. Privileged runs are left out: they do not communicate to know. With
    ``learned_only`` the scripted teams are left out too, so that the paper's methods, which
    sit far below the scripted teams here, get a front of their own."""
    points = sorted(
        (s["metrics"]["All"]["ACm"] or 0.0, s["metrics"]["All"]["Success"] or 0.0)
        for s in runs.values()
        if not s.get("privileged") and (learned_row(s) or not learned_only)
    )
    front: list[tuple[float, float]] = []
    for acm, success in points:
        if not front or success > front[-1][1]:
            if front and front[-1][0] == acm:
                front.pop()
            front.append((acm, success))
    return front


PARTIAL_COMMUNICATION = ("hangrcom", "condcomm", "cmprcomm", "intencomm")


def _success(summary: dict) -> str:
    m = summary["metrics"]["All"]
    return f"{summary['policy']} {m['Success']:.3f}{_interval(m, 'Success')}"


def _overlap(a: dict, b: dict) -> bool:
    """Whether the two runs' 95 % Success intervals overlap (the order is then unresolved)."""
    ia, ib = (s["metrics"]["All"].get("ci95", {}).get("Success") for s in (a, b))
    return ia is None or ib is None or (ia[0] <= ib[1] and ib[0] <= ia[1])


def _less(runs: dict[str, dict], low: str, high: str, strict: bool,
          played: dict[str, list[EpisodeRecord]]) -> tuple[str, str]:  # fmt: skip
    """Whether ``low``'s Success is below ``high``'s (or equal, unless ``strict``), by point
    estimate, with a word when the noise leaves the order open: the paired 95 % interval of
    low - high over the episodes both played includes zero, or, without both runs' episodes,
    the two runs' own intervals overlap."""
    if low not in runs or high not in runs:
        missing = [p for p in (low, high) if p not in runs]
        return "not run", "missing " + ", ".join(missing)
    a, b = runs[low]["metrics"]["All"]["Success"], runs[high]["metrics"]["All"]["Success"]
    verdict = "holds" if (a < b if strict else a <= b) else "fails"
    evidence = f"{_success(runs[low])} against {_success(runs[high])}"
    if low in played and high in played:
        d = paired_difference(played[low], played[high])
        lo, hi = d["Success"]["ci95"]
        evidence += (f"; paired {d['Success']['difference']:+.3f} [{lo:+.3f}, {hi:+.3f}] "
                     f"over {d['episodes']} episodes")  # fmt: skip
        if a != b and lo <= 0 <= hi:
            verdict += " (paired interval includes 0)"
    elif _overlap(runs[low], runs[high]) and a != b:
        verdict += " (intervals overlap)"
    return verdict, evidence


def orderings(runs: dict[str, dict], played: dict[str, list[EpisodeRecord]] | None = None,
              ) -> list[tuple[str, str, str]]:  # fmt: skip
    """The paper's orderings (Sections 6.3-6.5) checked on our learned rows of one setting:
    (claim, verdict, evidence); Success compared by point estimate, with a word where the noise
    leaves the order open. ``played`` (policy -> episodes) makes that word come from the paired
    interval, which is much narrower than two separate ones on the same episodes."""
    played = played or {}
    out = [
        ("SA < Ours", *_less(runs, "sa-learned", "hangrcom", True, played)),
        ("Ours <= CentralComm.", *_less(runs, "hangrcom", "centralcomm", False, played)),
        ("QMIX < Ours", *_less(runs, "qmix", "hangrcom", True, played)),
    ]
    missing = [p for p in (*PARTIAL_COMMUNICATION, "sa-learned") if p not in runs]
    claim = "Ours has the best CES among the partial-communication methods"
    if missing:
        out.append((claim, "not run", "missing " + ", ".join(missing)))
    else:
        sa = runs["sa-learned"]["metrics"]["All"]["Success"] or 0.0
        scores = {}
        for p in PARTIAL_COMMUNICATION:
            m = runs[p]["metrics"]["All"]
            scores[p] = ces(m["Success"], sa, m["ACm"]) if m["ACm"] else None
        sent = [v for v in scores.values() if v is not None]
        best = [p for p, v in scores.items() if sent and v == max(sent)]
        # CES is clipped at zero, so when SA beats every row they all tie: that is no "best".
        verdict = "holds" if best == ["hangrcom"] else "fails"
        if "hangrcom" in best and len(best) > 1:
            verdict += " (tied with " + ", ".join(p for p in best if p != "hangrcom") + ")"
        evidence = ", ".join(f"{p} {v:.1f}" if v is not None else f"{p} -"
                             for p, v in scores.items())  # fmt: skip
        out.append((claim, verdict, "CES " + evidence))
    for policy, name in ABLATIONS.items():
        out.append((f"{name} < Ours", *_less(runs, policy, "hangrcom", True, played)))
    return out


def orderings_table(runs: dict[str, dict], played: dict[str, list[EpisodeRecord]]) -> str:
    lines = ["| the paper's ordering | here | evidence (Success All [95 % interval]; paired: "
             "the first run's minus the second's over the episodes both played) |",
             "|---|---|---|"]  # fmt: skip
    lines += [f"| {c} | {v} | {e} |" for c, v, e in orderings(runs, played)]
    return "\n".join(lines)


def plot(runs_by_setting: dict[str, dict[str, dict]], reference: dict, out: Path) -> Path:
    import matplotlib.pyplot as plt
    from adjustText import adjust_text

    from maniskill_tidy.common.plotting import save_figure

    settings = sorted(runs_by_setting) or ["I"]
    fig, axes = plt.subplots(1, len(settings), figsize=(6 * len(settings), 4.2), squeeze=False)
    cols = reference["columns"]
    for ax, setting in zip(axes[0], settings, strict=True):
        labels, xs, ys = [], [], []
        for policy, s in runs_by_setting.get(setting, {}).items():
            m = s["metrics"]["All"]
            lo, hi = (m.get("ci95") or {}).get("Success", (m["Success"], m["Success"]))
            ax.errorbar(
                m["ACm"],
                m["Success"],
                yerr=[[m["Success"] - lo], [hi - m["Success"]]],
                fmt="o",
                markersize=7,
                capsize=3,
                zorder=3,
            )
            labels.append(ax.text(m["ACm"], m["Success"], policy, fontsize=8))
            xs.append(m["ACm"])
            ys.append(m["Success"])
        for name, values in reference["rows"].get(setting, {}).items():
            acm, suc = values[cols.index("ACm All")], values[cols.index("Success All")]
            if acm is None:
                continue
            ax.scatter(acm, suc, s=40, facecolors="none", edgecolors="grey", zorder=2)
            labels.append(ax.text(acm, suc, f"{name} (paper)", fontsize=7, color="grey"))
            xs.append(acm)
            ys.append(suc)
        fronts = (("Pareto front (ours)", False, "tab:red"),
                  ("Pareto front (our learned rows)", True, "tab:blue"))  # fmt: skip
        for label, learned_only, color in fronts:
            front = pareto_front(runs_by_setting.get(setting, {}), learned_only)
            if len(front) > 1:
                style = {"color": color, "ls": "--" if learned_only else "-", "label": label}
                ax.step([x for x, _ in front], [y for _, y in front], where="post", alpha=0.6,
                        zorder=1, **style)  # fmt: skip
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=8)
        ax.set(
            xlabel="ACm: values received per agent per step",
            ylabel="Success (All)",
            title=f"Setting {setting}: success against communication",
        )
        ax.grid(alpha=0.3)
        # rows that sit close together (the paper's BroadComm. and CentralComm., the heuristics
        # at ACm 0) would print their names over each other: move the labels apart, with an
        # iteration budget rather than adjustText's default time budget so the plot reproduces
        adjust_text(labels, x=xs, y=ys, ax=ax, iter_lim=300,
                    arrowprops={"arrowstyle": "-", "color": "grey", "lw": 0.5})  # fmt: skip
    return save_figure(fig, out)


FULL_PROTOCOL = Path("all") / "eval"  # under the leaderboard's root: eval --out eval/all


def write_leaderboard(root: Path = Path("eval")) -> Path:
    from maniskill_tidy.common.files import write_atomic

    root = Path(root)
    runs = collect(root)
    if not runs:  # before anything is written: an empty leaderboard helps nobody
        raise ValueError(
            f"{root}: no eval runs; expected {root}/results/setting_S/NAME/summary.json "
            "(`maniskill-tidy eval --out DIR` writes them under DIR/eval)"
        )
    full = collect(root / FULL_PROTOCOL)
    reference = paper_reference()
    parts = [
        "# Leaderboard",
        "",
        "Written by `maniskill-tidy leaderboard` from the run summaries under "
        "`eval/results/`; each row comes from `maniskill-tidy eval --policy NAME --setting S "
        "--split test --dataset DIR --env HeteroTidy-v1` (see the details table): a row "
        "without a look named was measured in HeteroTidy-v1, the flat look where the first "
        "rows were made; NAME-v2 rows in HeteroTidy-v2, the default look since its rows "
        "exist. Rows marked *(paper)* are the "
        "figures the paper reports (AI2-THOR/ProcTHOR, learned models): reference points, not "
        "runs of this code. *(privileged)* rows read the simulator state. Non-privileged teams "
        "use ground-truth instance segmentation in place of a trained detector, but in the "
        "pixels track's tables. Our "
        "Success cells give the 95 % bootstrap interval over episodes in brackets. The "
        "standard protocol is the first start of every meta-task of the test split "
        "(200 episodes per setting); the paper's full protocol plays all 1000.",
        "",
        "![success against communication](leaderboard.png)",
        "",
    ]
    numbers = {"I": ("3", "5"), "II": ("4", "6")}
    for setting in sorted(set(runs) | set(reference["rows"])):
        methods, ablations = numbers.get(setting, ("-", "-"))
        everything = runs.get(setting, {})
        ours = {p: s for p, s in everything.items() if not from_pixels(s)}
        parts += [f"## Setting {setting}", "",
                  f"Methods (the paper's Table {methods}):", "",
                  table(setting, ours, reference, "rows"), ""]  # fmt: skip
        if full.get(setting):
            parts += ["The paper's full protocol (every start of every meta-task of the test "
                      "split, `eval --policy NAME --episodes all --env HeteroTidy-v1 --out "
                      "eval/all`; the paper's rows are above):", "",
                      table(setting, full[setting], {}, "rows"), "", details(full[setting]),
                      ""]  # fmt: skip
        if any(p in ABLATIONS for p in ours) or reference.get("ablations", {}).get(setting):
            parts += [f"Ablations (the paper's Table {ablations}):", "",
                      table(setting, ours, reference, "ablations"), ""]  # fmt: skip
        if ours:
            played = episodes(root, setting, everything)
            parts += ["The paper's orderings on our learned rows:", "",
                      orderings_table(ours, played), ""]  # fmt: skip
            if len(ours) < len(everything):
                parts += ["From pixels (the pixels track, `eval --segmentation learned`): agents "
                          "see RGB-D only and find objects with the look's learned segmenter "
                          "(docs/pixels.md); each row beside the same team reading the "
                          "renderer's segmentation in the same look, the difference paired "
                          "over the episodes both played (95 % interval). *kept*: the share "
                          "of its ground-truth Success the team keeps.", "",
                          pixels_table(everything, played), ""]  # fmt: skip
            parts += ["Runs:", "", details(everything), ""]
    out = root / "LEADERBOARD.md"
    write_atomic(out, "\n".join(parts).encode())
    ground_truth = {k: {p: s for p, s in v.items() if not from_pixels(s)} for k, v in runs.items()}
    plot(ground_truth, reference, root / "leaderboard.png")
    return out
