"""What the forked episodes of ``training/memory_forks.py`` say about the pointer's best choices.

    python docs/research/probes/fork_pairs.py data/memory/setting_I/forks_memory-forks

Reads the run's checkpoint (``state.pt``: every pair so far) and prints, per (best choice's
kind, other choice's kind), how many forks there were, in how many the other choice did better
or worse, and the mean gain of the team return (the run's gamma); then how often a fork changed
the return by the decision's step and by who decided. With ``--pointer`` (the cloned
pointer's folder), whether the pairs can be predicted at all: a copy of that pointer is trained
on the pairs of all base episodes but the last ``--held-out`` ones, with no KL term, and both
pointers rank the held-out pairs whose returns differ. Nothing is written.

    python docs/research/probes/fork_pairs.py data/memory/setting_I/forks_memory-forks \
        --pointer agents/memory/setting_I --held-out 12
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from maniskill_tidy.policies.memory_candidates import KINDS


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a forks run's folder (data/memory/setting_S/forks_NAME)")
    p.add_argument("--pointer", type=Path, help="the cloned pointer's folder (agents/NAME/...)")
    p.add_argument(
        "--held-out",
        type=int,
        default=12,
        help="base episodes held out, the last (a round, if every base was forked)",
    )
    p.add_argument("--epochs", type=int, default=60)
    args = p.parse_args()
    ckpt = args.run / "state.pt"
    if not ckpt.is_file():
        p.error(f"{ckpt} not found; expected the folder of a forks run")
    state = torch.load(ckpt, weights_only=False)
    pairs, gamma = state["pairs"], json.loads(state["key"])["forks"]["gamma"]
    table: dict[tuple[str, str], list[tuple[float, float]]] = defaultdict(list)
    for part in pairs:
        rows = np.arange(len(part["gain"]))
        best = part["kind"][rows, part["best"]]
        other = part["kind"][rows, part["other"]]
        # runs before 2026-11-29's review kept only the discounted gain
        at_end = part.get("placed_gain", np.full(len(rows), np.nan))
        for b, o, g, e in zip(best, other, part["gain"], at_end, strict=True):
            table[(KINDS[int(b)], KINDS[int(o)])].append((float(g), float(e)))
    total = sum(len(v) for v in table.values())
    print(
        f"{total} forks in {len(pairs)} base episodes; the team return (gamma {gamma}), then "
        "the share placed at the end (undiscounted, what the metrics see; n/a in older runs)"
    )
    print(f"{'best':>8} -> {'other':<8} {'forks':>6} {'better':>7} {'worse':>6} {'mean gain':>10}"
          f" {'end better':>11} {'end worse':>10}")  # fmt: skip
    for (b, o), both in sorted(table.items(), key=lambda kv: -len(kv[1])):
        g, e = np.array(both).T
        end = "n/a" if np.isnan(e).all() else f"{(e > 0).sum():>11} {(e < 0).sum():>10}"
        print(f"{b:>8} -> {o:<8} {len(g):>6} {(g > 0).sum():>7} {(g < 0).sum():>6} "
              f"{g.mean():>+10.4f} {end:>11}")  # fmt: skip
    when_and_who(pairs)
    if args.pointer is not None:
        held_out(pairs, args.pointer, args.held_out, args.epochs)


def when_and_who(pairs: list[dict]) -> None:
    """How often a fork changed the return, by the decision's step and by who decided."""
    from maniskill_tidy.policies.memory_candidates import CONTEXT

    gain = np.concatenate([p["gain"] for p in pairs])
    context = np.concatenate([p["context"] for p in pairs])
    t = context[:, CONTEXT.index("time")] * 300
    manipulator = context[:, CONTEXT.index("manipulation")] > 0.5
    groups = [(f"steps {lo}-{hi - 1}", (t >= lo) & (t < hi))
              for lo, hi in ((0, 50), (50, 100), (100, 200), (200, 300))]  # fmt: skip
    groups += [("manipulators", manipulator), ("the others", ~manipulator)]
    for name, m in groups:
        print(
            f"{name:>14}: {int(m.sum()):>4} forks, {int((gain[m] != 0).sum()):>3} changed the "
            f"return ({int((gain[m] > 0).sum())} better, {int((gain[m] < 0).sum())} worse)"
        )


def held_out(pairs: list[dict], folder: Path, n: int, epochs: int) -> None:
    import copy

    from maniskill_tidy.models.checkpoints import load_memory
    from maniskill_tidy.policies.agent_config import MemoryConfig
    from maniskill_tidy.training.memory_forks import _margin, _stack, preference_update
    from maniskill_tidy.training.memory_reinforce import INPUTS

    if not 0 < n < len(pairs):
        raise SystemExit(f"--held-out {n}: expected between 1 and {len(pairs) - 1} base episodes")
    cloned = load_memory(folder)[0].eval()
    train, test = _stack(pairs[:-n]), _stack(pairs[-n:])
    fitted = copy.deepcopy(cloned).train()
    f = {**MemoryConfig.FORKS, "kl": 0.0, "epochs": epochs, "lr": 1e-3}
    stats = preference_update(fitted, cloned, torch.optim.Adam(fitted.parameters(), lr=f["lr"]),
                              train, [train[k] for k in INPUTS], f,
                              torch.Generator().manual_seed(0))  # fmt: skip
    informative = test["gain"] != 0
    rows = [test[k][informative] for k in INPUTS]
    best, other, gain = (test[k][informative] for k in ("best", "other", "gain"))
    print(
        f"fitted on {stats['pairs']} pairs ({stats['ranked_right']:.3f} of them ranked right); "
        f"{len(gain)} held-out pairs, the other choice better in {(gain > 0).float().mean():.3f}"
    )
    for name, model in (("cloned", cloned), ("fitted", fitted.eval())):
        with torch.no_grad():
            right = (_margin(model(*rows), best, other) > 0) == (gain > 0)
        print(f"  {name} pointer ranks {right.float().mean():.3f} of the held-out pairs right")


if __name__ == "__main__":
    main()
