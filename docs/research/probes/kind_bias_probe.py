"""Whole-policy changes of the object-memory pointer, compared on the same episodes.

    python docs/research/probes/kind_bias_probe.py agents/memory.yaml --setting I --episodes 48 \
        --bias explore=-2 --bias inspect=2 --bias park=2

Plays the trained pointer (``agents/NAME/setting_S``, best choices) on ``--episodes`` train
episodes (a fixed draw, seed 0), then the same pointer with each ``--bias KIND=B`` added to the
scores of that kind's candidates (``models.memory_pointer.KindBias``), and prints each change
paired against the pointer: the share of objects put where they belong and Success, with 95 %
intervals, and how many decisions' margins such a bias can flip at all. The train split, never
val or test: a probe of whether a few numbers move the outcome, before any search over them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from maniskill_tidy.models.checkpoints import WEIGHTS
from maniskill_tidy.policies.agent_config import MemoryConfig
from maniskill_tidy.policies.memory_candidates import KINDS


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("config", type=Path, help="an object-memory config (agents/memory.yaml)")
    p.add_argument("--setting", default="I", choices=["I", "II"])
    p.add_argument("--episodes", type=int, default=48)
    p.add_argument("--bias", action="append", default=[], help="KIND=NUMBER, repeatable")
    args = p.parse_args()
    biases = []
    for b in args.bias:
        kind, _, value = b.partition("=")
        try:
            biases.append((kind, KINDS.index(kind), float(value)))
        except ValueError:
            p.error(f"--bias {b!r}: expected KIND=NUMBER with KIND one of {list(KINDS)}")
    from maniskill_tidy.envs.episodes import EpisodeSet
    from maniskill_tidy.training.memory_forks import paired_gain
    from maniskill_tidy.training.memory_reinforce import play_jobs

    cfg = MemoryConfig.load(args.config)
    path = Path(cfg.out) / f"setting_{args.setting}" / WEIGHTS
    if not path.is_file():
        p.error(f"{path} not found; expected a pointer trained by `maniskill-tidy train`")
    n = len(EpisodeSet.for_setting(cfg.dataset, "train", args.setting).episodes)
    chosen = sorted(np.random.default_rng(0).choice(n, args.episodes, replace=False).tolist())
    mode = {"gamma": 1.0, "bonus": 1.0}
    runs = [("pointer", [0.0] * len(KINDS))]
    for kind, k, value in biases:
        bias = [0.0] * len(KINDS)
        bias[k] = value
        runs.append((f"{kind}{value:+g}", bias))
    jobs = [(i, str(path), mode | {"bias": bias, "keep": True}) for _, bias in runs
            for i in chosen]  # fmt: skip
    played = play_jobs(cfg, args.config, args.setting, "train", jobs, "episodes", True)
    by_run = [played[j * len(chosen) : (j + 1) * len(chosen)] for j in range(len(runs))]
    base = by_run[0]
    flips = _flippable(base, path.parent)
    print(f"{len(chosen)} train episodes, Setting {args.setting}; the pointer placed "
          f"{np.mean([e['reasonable'] / max(e['k'], 1) for e in base]):.3f}")  # fmt: skip
    for (name, bias), eps in zip(runs[1:], by_run[1:], strict=True):
        g = paired_gain(eps, base)
        k = int(np.argmax(np.abs(bias)))
        print(f"{name:>12}: placed {g['placed']['difference']:+.3f} {g['placed']['ci95']} "
              f"({g['placed']['better']} better, {g['placed']['worse']} worse), Success "
              f"{g['success']['difference']:+.3f} {g['success']['ci95']}; the pointer's "
              f"decisions this bias could flip: {flips(k, bias[k]):.3f}")  # fmt: skip


def _flippable(base: list[dict], folder: Path):
    """The share of the pointer's decisions (kept in ``base``) whose choice a bias of ``value``
    on kind ``k`` changes, all else equal (the first it changes in an episode changes the rest)."""
    from maniskill_tidy.models.checkpoints import load_memory
    from maniskill_tidy.training.memory_reinforce import INPUTS

    rows = {k: torch.from_numpy(np.concatenate([e[k] for e in base])) for k in (*INPUTS, "slot")}
    with torch.no_grad():
        scores = load_memory(folder)[0](*(rows[k] for k in INPUTS))
    kinds = rows["kind"].long()

    def share(k: int, value: float) -> float:
        biased = scores + value * (kinds == k)
        return float((biased.argmax(-1) != rows["slot"]).float().mean())

    return share


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
