"""Maintainers: extract the paper's Tables 3-6 into ``paper_reference.json`` (package data):
methods (Tables 3-4) under ``rows``, ablations (Tables 5-6) under ``ablations``.

``python -m maniskill_tidy.eval.paper_tables PAPER.tex`` rewrites the file; the leaderboard only
reads the JSON, never the paper.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from maniskill_tidy.eval.leaderboard import COLUMNS
from maniskill_tidy.eval.metrics import SPLITS

TABLES = {"quan1": ("rows", "I"), "quan2": ("rows", "II"),
          "abla1": ("ablations", "I"), "abla2": ("ablations", "II")}  # fmt: skip
BOLD = re.compile(r"\\textbf\{(.*?)\}")


def extract(tex: str) -> dict:
    tables: dict[str, dict[str, dict[str, list[float | None]]]] = {"rows": {}, "ablations": {}}
    for label, (kind, setting) in TABLES.items():
        if "\\label{" + label + "}" not in tex and kind == "ablations":
            continue  # a text with the methods' tables only
        start = tex.index("\\label{" + label + "}")
        body = tex[start : tex.index("\\end{tabular}", start)]
        rows = tables[kind]
        rows[setting] = {}
        for line in body.splitlines():
            line = line.replace("\\rowcolor{lightgray!30}", "").strip()
            if "&" not in line or "multirow" in line or line.startswith("& Single"):
                continue
            cells = [BOLD.sub(r"\1", c).strip().strip("{} \\") for c in line.split("&")]
            rows[setting][cells[0]] = [
                None if c in ("-", "") else float(c) for c in cells[1 : 1 + 3 * len(COLUMNS)]
            ]
    return {
        "source": "Tables 3-6 of the paper (heterogeneous-embodied-multi-agent-collaboration), "
        "AI2-THOR/ProcTHOR, reported figures",
        "columns": [f"{m} {s}" for m in COLUMNS for s in SPLITS],
        **tables,
    }


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        raise SystemExit("usage: python -m maniskill_tidy.eval.paper_tables PAPER.tex")
    out = Path(__file__).with_name("paper_reference.json")
    out.write_text(json.dumps(extract(Path(argv[0]).read_text()), indent=1))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
