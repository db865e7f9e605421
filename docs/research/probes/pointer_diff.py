"""Where two object-memory pointers choose differently, on the teacher's recorded decisions.

    python docs/research/probes/pointer_diff.py agents/memory/setting_I \
        agents/experiments/memory-ppo/setting_I --rows data/memory/setting_I/val

Both pointers score the same recorded candidates (``training/memory_data.py``: the states the
teacher met); prints how many choices differ, as (first's kind, second's kind) pairs, and for
the most common pair the deciding agents' capabilities, the time and the share of the house
they had searched. Nothing is written.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np
import torch

from maniskill_tidy.models.checkpoints import load_memory
from maniskill_tidy.policies.memory_candidates import CONTEXT, KINDS
from maniskill_tidy.training.memory_data import load_memory_rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("first", type=Path, help="a trained pointer's folder (agents/NAME/setting_S)")
    p.add_argument("second", type=Path)
    p.add_argument("--rows", type=Path, required=True, help="recorded decisions (a split folder)")
    args = p.parse_args()

    rows = load_memory_rows(args.rows)
    if not rows:
        raise SystemExit(f"{args.rows}: no recorded decisions (house_*.npz) there")
    x = [torch.from_numpy(np.ascontiguousarray(rows[k]))
         for k in ("kind", "type", "rest", "numeric", "context")]  # fmt: skip
    pointers = [load_memory(f)[0] for f in (args.first, args.second)]
    for folder, pointer in zip((args.first, args.second), pointers, strict=True):
        if pointer.numeric != x[3].shape[-1]:
            p.error(f"{folder} reads {pointer.numeric} numbers per candidate, the rows "
                    f"{x[3].shape[-1]}; expected pointers of the rows' explore")  # fmt: skip
    with torch.no_grad():
        first, second = (pointer(*x).argmax(-1) for pointer in pointers)
    kind, context = x[0], x[4]
    k1, k2 = (kind.gather(1, c[:, None])[:, 0] for c in (first, second))
    differ = first != second
    print(f"{len(first)} decisions, {int(differ.sum())} chosen differently "
          f"({float(differ.float().mean()):.3f})")  # fmt: skip
    changed = zip(k1[differ].tolist(), k2[differ].tolist(), strict=True)
    pairs = Counter((KINDS[a], KINDS[b]) for a, b in changed)
    for (a, b), n in pairs.most_common():
        print(f"  {a} -> {b}: {n}")
    if not pairs:
        return
    (a, b), _ = pairs.most_common(1)[0]
    sel = differ & (k1 == KINDS.index(a)) & (k2 == KINDS.index(b))
    caps = Counter(tuple(int(v) for v in context[i, :3].tolist()) for i in torch.nonzero(sel)[:, 0])
    time, searched = CONTEXT.index("time"), CONTEXT.index("searched")
    print(
        f"{a} -> {b}: capabilities (navigation, manipulation, high camera) {dict(caps)}; "
        f"of all {int((k1 == KINDS.index(a)).sum())} {a} choices of the first"
    )
    for name, col in (("step / 300", time), ("share searched", searched)):
        q = np.percentile(context[sel][:, col].numpy(), [10, 50, 90])
        print(f"  {name}: 10/50/90 % {q.round(2).tolist()}")


if __name__ == "__main__":
    main()
