"""Why a run's failed episodes failed, object by object: every misplaced object left in an
unreasonable place, whether any agent ever picked it up, and the most pixels any manipulator's
camera had of it in one frame (PickUp needs ``MIN_PIXELS``). It replays the run's failed
episodes with the run's own team, env version and seeds.

    .venv/bin/python scripts/unsolved_objects.py eval/results/setting_I/expert-v2

An instrument, like the recorder: it reads the simulator, the teams do not.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env
from maniskill_tidy.policies import make_team


class ManipulatorPixels:
    """The largest pixel count of each misplaced object in one manipulator camera frame."""

    def start(self, env, team, channel) -> None:
        self.env = env
        self.most: dict[str, int] = {o: 0 for o in env.misplaced}

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        u = self.env
        by_seg = {u.manipulation.seg_of_object[o]: o for o in u.misplaced}
        for a in u.agents:
            if not a.capability[1]:
                continue
            ids, counts = np.unique(np.asarray(obs[a.name]["segmentation"]), return_counts=True)
            for i, n in zip(ids, counts, strict=True):
                if int(i) in by_seg:
                    o = by_seg[int(i)]
                    self.most[o] = max(self.most[o], int(n))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="an eval run folder (eval/results/setting_S/NAME)")
    p.add_argument("--dataset", help="the dataset it ran on, if moved (default: run.json's)")
    args = p.parse_args()
    run = json.loads((args.run / "run.json").read_text())
    records = [json.loads(line) for line in (args.run / "episodes.jsonl").read_text().splitlines()]
    failed = [r for r in records if not r["success"]]
    cfg = RunConfig(
        run["policy"], run["setting"], run["split"], args.dataset or run["dataset"],
        run["episodes"], run["seed"], run["task_type"], run.get("env", "HeteroTidy-v1"),
    )  # fmt: skip
    env = make_env(cfg, True)  # every camera: the pixel counts need the manipulators' images
    u = env.unwrapped
    index = {u.episodes.get(i).id: i for i in range(len(u.episodes))}
    print(f"{len(failed)} of {len(records)} episodes failed ({cfg.policy}, {cfg.env})")
    print("episode | object | type | picked up | most manipulator pixels in a frame")
    for r in failed:
        i = index[r["episode"]]
        pixels = ManipulatorPixels()
        play_episode(env, make_team(cfg.policy), i, cfg.seed + i, [pixels])
        outcome = u.evaluate()
        picked = set(outcome["picked"])
        for o in sorted(set(u.misplaced) - set(outcome["reasonable"])):
            kind = u.manipulation.types[o]
            note = "" if pixels.most[o] >= MIN_PIXELS else f" (< {MIN_PIXELS})"
            print(f"{r['episode']} | {o} | {kind} | {o in picked} | {pixels.most[o]}{note}")
    env.close()


if __name__ == "__main__":
    main()
