"""Expert demonstrations, as the paper's Section 4 describes them.

The privileged expert (``policies/expert.py``) plays every start configuration (5 per meta-task)
of a split's tasks. Per step and agent it reports the sub-task ``(Explore | Place, o, p, r)`` and
the sub-goal ``(dx, dy, drot, ope, stop)`` (``policies/base.py``: dx to the right and dy ahead in
0.25 m cells within -4..4, drot in {0, 90, 180, 270}, ope in NoAction / PickUp / PutDown / Drop),
together with the action it took and where the agent stood.

File format (``DIR/setting_S/SPLIT/``):

- ``house_NNNNN.jsonl.gz``: one line per trajectory::

    {"episode": "house_00000/task_3/start_2", "house": ..., "task": ..., "start": 2,
     "setting": "I", "team": [[1,0,0], ...], "agents": ["agent_0", ...], "seed": 17,
     "success": true, "length": 88, "k": 3, "task_kind": "Cross",
     "steps": [ {"agent_0": {"pose": [x, y, rot, horizon], "held": null | "Apple_0",
                             "action": 0, "target": null | "Apple_0" | "Fridge_0/shelf_1",
                             "subtask": ["Place", "Apple", "Fridge", "Kitchen"],
                             "subgoal": [dx, dy, drot, "PickUp", false]}, ...}, ... ]}

  Agents that have stopped have no entry in later steps. Observations are not stored: the env
  is deterministic, so replaying the actions from the same episode and seed reproduces them
  (``replay_observations``).
- ``manifest.json``: dataset hash, counts, expert success rate, code version and this format's
  version. Shards are written atomically, one per house; a rerun skips finished houses.
"""

from __future__ import annotations

import gzip
import json
from collections import defaultdict
from dataclasses import astuple
from pathlib import Path

from tqdm import tqdm

from maniskill_tidy.common.files import write_atomic
from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.training.house_jobs import check_same_config

FORMAT_VERSION = 1


def _encode_action(action) -> tuple[int, str | None]:
    if isinstance(action, Targeted):
        return int(action.action), action.target
    return int(Action(int(action))), None


class TrajectoryLog:
    """An episode observer (``eval/episode.py``) that keeps the expert's per-step labels."""

    def start(self, env, team, channel) -> None:
        self.env, self.steps = env, []

    def decided(self, t: int, actions: dict, labels: dict) -> None:
        u, step = self.env, {}
        for a in u.agents:
            if a.name not in actions:
                continue
            code, target = _encode_action(actions[a.name])
            subtask, subgoal = labels[a.name]
            x, y = u.house.navgrid.center(*a.cell)
            step[a.name] = {
                "pose": [round(x, 3), round(y, 3), a.rotation, a.horizon],
                "held": a.held,
                "action": code,
                "target": target,
                "subtask": list(astuple(subtask)),
                "subgoal": list(astuple(subgoal)),
            }
        self.steps.append(step)


def record_trajectory(env, team, index: int, seed: int) -> dict:
    """Play episode ``index`` with the expert and return its trajectory (format above)."""
    from maniskill_tidy.eval.episode import play_episode

    log = TrajectoryLog()
    record = play_episode(env, team, index, seed, [log])
    u = env.unwrapped
    return {
        "episode": u.episode.id,
        "house": u.episode.house_id,
        "task": u.episode.task.id,
        "start": u.episode.start,
        "setting": u.setting,
        "team": [list(c) for c in u.team],
        "agents": list(u.agent_names),
        "seed": seed,
        "success": record.success,
        "length": record.length,
        "k": record.k,
        "task_kind": u.episode.task.kind,
        "steps": log.steps,
    }


def write_demonstrations(
    out: Path,
    dataset: str | None,
    split: str = "train",
    setting: str = "I",
    tasks: int | None = None,
    seed: int = 0,
    progress: bool = True,
    env_id: str = "HeteroTidy-v1",
) -> dict:
    """Write the expert's trajectories for a split (resumable per house); returns the manifest.
    ``env_id`` is the look: no image is stored, but what the expert's cameras see decides
    whether a PickUp succeeds, so each look has its own trajectories."""
    import gymnasium as gym

    from maniskill_tidy.common.provenance import code_version
    from maniskill_tidy.policies.expert import ExpertTeam

    env = gym.make(
        env_id,
        setting=setting,
        dataset=dataset,
        split=split,
        obs_mode="none",
        reward_mode="none",
    )
    u = env.unwrapped
    episodes = u.episodes.episodes
    task_ids = sorted(
        {e.task.id for e in episodes}, key=lambda t: [e.task.id for e in episodes].index(t)
    )
    keep = set(task_ids[:tasks] if tasks is not None else task_ids)
    by_house: dict[str, list[int]] = defaultdict(list)
    for i, e in enumerate(episodes):
        if e.task.id in keep:
            by_house[e.house_id].append(i)
    directory = Path(out) / f"setting_{setting}" / split
    look = {"env": env_id} if env_id != "HeteroTidy-v1" else {}  # v1 folders predate the field
    want = {"setting": setting, "split": split, "dataset_hash": u.episodes.dataset_hash,
            "seed": seed, **look}  # fmt: skip
    check_same_config(directory / "manifest.json", want)
    directory.mkdir(parents=True, exist_ok=True)
    team = ExpertTeam()
    total = sum(len(v) for v in by_house.values())
    bar = tqdm(
        total=total, desc=f"demonstrations {setting} {split}", unit="traj", disable=not progress
    )
    counts = {"trajectories": 0, "successes": 0, "steps": 0}
    for house, indices in sorted(by_house.items()):
        shard = directory / f"{house}.jsonl.gz"
        if shard.exists():
            lines = gzip.decompress(shard.read_bytes()).decode().splitlines()
            trajectories = [json.loads(x) for x in lines]
        else:
            trajectories = [record_trajectory(env, team, i, seed + i) for i in indices]
            body = "".join(json.dumps(t, sort_keys=True) + "\n" for t in trajectories)
            write_atomic(shard, gzip.compress(body.encode(), mtime=0))
        counts["trajectories"] += len(trajectories)
        counts["successes"] += sum(t["success"] for t in trajectories)
        counts["steps"] += sum(len(t["steps"]) for t in trajectories)
        bar.update(len(indices))
    bar.close()
    env.close()
    manifest = {
        "format_version": FORMAT_VERSION,
        "setting": setting,
        "split": split,
        "dataset_hash": u.episodes.dataset_hash,
        "houses": len(by_house),
        **counts,
        "expert_success": counts["successes"] / max(counts["trajectories"], 1),
        "seed": seed,
        **look,
        "code_version": code_version(),
    }
    write_atomic(directory / "manifest.json", json.dumps(manifest, indent=1).encode())
    return manifest


def read_demonstrations(directory: Path) -> list[dict]:
    """Every trajectory under ``directory`` (a ``setting_S/SPLIT`` folder)."""
    out = []
    for shard in sorted(Path(directory).glob("*.jsonl.gz")):
        out += [json.loads(x) for x in gzip.decompress(shard.read_bytes()).decode().splitlines()]
    return out
