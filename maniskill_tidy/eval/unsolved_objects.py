"""Why a run's failed episodes failed, object by object: every misplaced object left in an
unreasonable place, whether any agent ever picked it up, and the most pixels any manipulator's
camera had of it in one frame (PickUp needs ``MIN_PIXELS``). It replays the run's failed
episodes with the run's own team, env version and seeds.

    maniskill-tidy unsolved-objects eval/results/setting_I/expert-v2

An instrument, like the recorder: it reads the simulator, the teams do not.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from maniskill_tidy.envs.actions import MIN_PIXELS
from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env, make_run_team


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


def unsolved_objects(run_dir: Path, dataset: str | None = None) -> list[str]:
    """The report's lines: per failed episode of the run, each object left unreasonable."""
    for name in ("run.json", "episodes.jsonl"):
        if not (run_dir / name).is_file():
            raise ValueError(f"{run_dir}: no {name}; expected an eval run's folder "
                             "(eval/results/setting_S/NAME)")  # fmt: skip
    run = json.loads((run_dir / "run.json").read_text())
    records = [json.loads(line) for line in (run_dir / "episodes.jsonl").read_text().splitlines()]
    failed = [r for r in records if not r["success"]]
    cfg = RunConfig(
        run["policy"], run["setting"], run["split"], dataset or run["dataset"],
        run["episodes"], run["seed"], run["task_type"], run.get("env", "HeteroTidy-v1"),
        segmentation=run.get("segmentation", "ground-truth"),
    )  # fmt: skip
    env = make_env(cfg, True)  # every camera: the pixel counts need the manipulators' images
    u = env.unwrapped
    index = {u.episodes.get(i).id: i for i in range(len(u.episodes))}
    lines = [
        f"{len(failed)} of {len(records)} episodes failed ({cfg.policy}, {cfg.env})",
        "episode | object | type | picked up | most manipulator pixels in a frame",
    ]
    try:
        for r in failed:
            i = index[r["episode"]]
            pixels = ManipulatorPixels()
            play_episode(env, make_run_team(cfg), i, cfg.seed + i, [pixels])
            outcome = u.evaluate()
            picked = set(outcome["picked"])
            for o in sorted(set(u.misplaced) - set(outcome["reasonable"])):
                kind = u.manipulation.types[o]
                note = "" if pixels.most[o] >= MIN_PIXELS else f" (< {MIN_PIXELS})"
                lines.append(f"{r['episode']} | {o} | {kind} | {o in picked} | "
                             f"{pixels.most[o]}{note}")  # fmt: skip
    finally:
        env.close()
    return lines
