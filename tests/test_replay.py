"""The committed leaderboard runs replay to the same records (all but wall time): the 120-house
dataset regenerated from its seed, the runs' first episodes played again with today's code.

A change that alters a record on purpose must say so and re-run the rows it touches; any
other difference is a regression (a refactor that changed behaviour)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

RESULTS = Path(__file__).parents[1] / "eval" / "results"


@pytest.fixture(scope="module")
def tidy120(tmp_path_factory) -> Path:
    from maniskill_tidy.tasks.dataset import generate_dataset

    data = tmp_path_factory.mktemp("replay") / "tidy120"
    generate_dataset(data, 120, seed=0, workers=2, progress=False)
    return data


def replay(data: Path, row: str, setting: str, episodes: int) -> None:
    """Replays a row's first episodes (``expert-v2``: the expert on HeteroTidy-v2)."""
    from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode, select
    from maniskill_tidy.policies import make_team

    committed = RESULTS / f"setting_{setting}" / row
    run = json.loads((committed / "run.json").read_text())
    policy = run["policy"]
    manifest = json.loads((data / "manifest.json").read_text())
    assert manifest["dataset_hash"] == run["dataset_hash"]
    before = {
        r["episode"]: r
        for r in map(json.loads, (committed / "episodes.jsonl").read_text().splitlines())
    }
    cfg = RunConfig(policy, setting, "test", str(data), env=run.get("env", "HeteroTidy-v1"))
    env, team = make_env(cfg), make_team(policy)
    try:
        starts = [e.start for e in env.unwrapped.episodes.episodes]
        for index in select(starts, "standard")[:episodes]:  # the run's first, seed = index
            r = run_episode(env, team, index, cfg.seed + index).to_dict()
            old = before[r["episode"]]
            assert {k: v for k, v in r.items() if k != "seconds"} == {
                k: v for k, v in old.items() if k != "seconds"
            }, (row, setting, r["episode"])
    finally:
        env.close()


@pytest.mark.parametrize(
    "row", ["expert", "heuristic-none", "hangrcom", "memory", "heuristic-none-v2"]
)
def test_a_committed_episode_replays_identically(tidy120, row):
    replay(tidy120, row, "I", 1)


@pytest.mark.slow
@pytest.mark.parametrize(
    "policy, setting",
    [
        ("expert", "I"),
        ("heuristic-none", "I"),
        ("heuristic-broadcast", "I"),
        ("heuristic-detection", "I"),
        ("heuristic-central", "II"),
        ("sa", "I"),
        ("hangrcom", "I"),
        ("hangrcom", "II"),
        ("memory", "I"),
        ("memory", "II"),
        ("expert-v2", "I"),  # v2's rows: its robots and lighting as shipped
        ("heuristic-none-v2", "II"),
        ("heuristic-broadcast-v2", "I"),
    ],
)
def test_committed_episodes_replay_identically(tidy120, policy, setting):
    replay(tidy120, policy, setting, 5)  # five each
