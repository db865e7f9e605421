"""Expert demonstrations: the documented format, label ranges, and replays that reproduce them."""

from __future__ import annotations

import gymnasium as gym
import pytest

import maniskill_tidy  # noqa: F401
from maniskill_tidy.envs.actions import Targeted
from maniskill_tidy.policies.base import OPERATIONS
from maniskill_tidy.training.demonstrations import read_demonstrations, write_demonstrations


def test_demonstrations_hold_labels_in_range_and_replay_exactly(tmp_path):
    manifest = write_demonstrations(tmp_path, None, "train", "I", tasks=1, progress=False)
    assert manifest["trajectories"] == 5 and manifest["houses"] == 1
    trajectories = read_demonstrations(tmp_path / "setting_I" / "train")
    assert len(trajectories) == 5 and {t["start"] for t in trajectories} == set(range(5))
    for t in trajectories:
        assert t["length"] == len(t["steps"])  # the last agent to stop acted every step
        for step in t["steps"]:
            for label in step.values():
                kind, *_ = label["subtask"]
                dx, dy, drot, ope, stop = label["subgoal"]
                assert kind in ("Explore", "Place")
                assert -4 <= dx <= 4 and -4 <= dy <= 4 and drot in (0, 90, 180, 270)
                assert ope in OPERATIONS and isinstance(stop, bool)
    # replaying the recorded actions in a fresh env reproduces the outcome
    t = trajectories[0]
    env = gym.make("HeteroTidy-v1", obs_mode="none", split="train")
    try:
        env.reset(seed=t["seed"], options={"episode": t["episode"]})
        for step in t["steps"]:
            actions = {
                name: Targeted(a["action"], a["target"]) if a["target"] else a["action"]
                for name, a in step.items()
            }
            _, _, terminated, truncated, info = env.step(actions)
        assert info["success"] == t["success"]
        assert terminated or truncated
    finally:
        env.close()
    # a second call finds the shard and does not redo it
    again = write_demonstrations(tmp_path, None, "train", "I", tasks=1, progress=False)
    assert again["trajectories"] == 5 and again["steps"] == manifest["steps"]
    # the look decides what the expert's cameras see, so v2 trajectories are refused in v1's
    # folder (and the other way round), before anything is played
    with pytest.raises(ValueError, match=r"other settings \(env\)"):
        write_demonstrations(tmp_path, None, "train", "I", tasks=1, progress=False,
                             env_id="HeteroTidy-v2")  # fmt: skip
