"""Policy improvement for the memory pointer from forked episodes (training/memory_forks.py)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from maniskill_tidy.policies.agent_config import MemoryConfig
from tests.test_memory_team import memory_config

INPUTS = ("kind", "type", "rest", "numeric", "context")


def _pointer():
    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import MemoryPointer

    torch.manual_seed(0)
    return MemoryPointer(type_vectors(), kinds=6, receptacles=10, numeric=9, context=10).eval()


def _rows(n: int, g: torch.Generator) -> dict[str, torch.Tensor]:
    """Decisions over (fetch, explore, park) and a padded slot."""
    return {
        "kind": torch.tensor([[0, 3, 5, -1]]).repeat(n, 1),
        "type": torch.full((n, 4), 4),
        "rest": torch.full((n, 4), 10),
        "numeric": torch.rand(n, 4, 9, generator=g),
        "context": torch.rand(n, 10, generator=g),
    }


def test_pairs_teach_the_better_choice_and_the_kl_term_holds_the_rest():
    from maniskill_tidy.training.memory_forks import preference_update

    cloned = _pointer()
    g = torch.Generator().manual_seed(3)
    n = 96
    # explore (slot 1) was the best choice; fetching (0) did better, parking (2) worse, and a
    # third of the forks changed nothing (no signal: left out)
    other = torch.tensor([0, 2, 0] * (n // 3))
    gain = torch.tensor([0.05, -0.02, 0.0] * (n // 3))
    pairs = _rows(n, g) | {"best": torch.ones(n, dtype=torch.long), "other": other, "gain": gain}
    decisions = [_rows(64, g)[k] for k in INPUTS]
    rows = [pairs[k] for k in INPUTS]

    def margins(kl: float):
        policy = copy.deepcopy(cloned).train()
        optimiser = torch.optim.Adam(policy.parameters(), lr=3e-3)
        f = {**MemoryConfig.FORKS, "kl": kl, "epochs": 5, "batch": 32}
        stats = preference_update(policy, cloned, optimiser, pairs, decisions, f,
                                  torch.Generator().manual_seed(0))  # fmt: skip
        assert stats["pairs"] == 64  # the forks that changed nothing are not pairs
        with torch.no_grad():
            s = policy(*rows)
        return float((s[:, 0] - s[:, 1]).mean()), float((s[:, 2] - s[:, 1]).mean()), stats

    with torch.no_grad():
        s = cloned(*rows)
        fetch0, park0 = float((s[:, 0] - s[:, 1]).mean()), float((s[:, 2] - s[:, 1]).mean())
    fetch, park, stats = margins(0.0)
    assert fetch > 0 > park and fetch > fetch0 and park < park0
    assert stats["ranked_right"] == 1.0 and stats["kl_cloned"] > 0
    held, _, held_stats = margins(50.0)
    assert fetch0 < held < fetch
    assert held_stats["kl_cloned"] < stats["kl_cloned"]


def test_forks_choose_another_present_candidate_at_decisions_with_a_choice():
    from maniskill_tidy.training.memory_forks import choose_forks, pairs_of

    g = torch.Generator().manual_seed(4)
    base = {k: v.numpy() for k, v in _rows(6, g).items()}
    base["kind"][0] = [5, -1, -1, -1]  # only parking: nothing to fork
    base["slot"] = np.array([0, 1, 1, 0, 2, 1])
    base["agent"], base["n"] = np.array([0, 0, 1, 1, 2, 2]), np.array([0, 1, 0, 1, 0, 1])
    base["return"], base["reasonable"], base["k"], base["success"] = 0.5, 1, 2, False
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(30):
        for agent, n, slot in choose_forks(_pointer(), base, 3, 2.0, rng):
            row = int(np.flatnonzero((base["agent"] == agent) & (base["n"] == n))[0])
            assert row != 0 and slot != base["slot"][row] and base["kind"][row, slot] >= 0
            seen.add(row)
    assert seen == {1, 2, 3, 4, 5}
    forks = [
        {"override": (1, 0, 0), "return": 0.75, "reasonable": 2, "success": True},
        {"override": (2, 1, 2), "return": 0.25, "reasonable": 1, "success": False},
    ]
    pairs = pairs_of(base, forks)
    assert pairs["best"].tolist() == [1, 1] and pairs["other"].tolist() == [0, 2]
    assert pairs["gain"].tolist() == [0.25, -0.25]
    # the second fork placed as many objects, only later: worse discounted, equal at the end
    assert pairs["placed_gain"].tolist() == [0.5, 0.0]
    assert pairs["success_gain"].tolist() == [1, 0]
    assert np.array_equal(pairs["numeric"], base["numeric"][[2, 5]])


def test_paired_gain_counts_the_shared_episodes():
    from maniskill_tidy.training.memory_forks import paired_gain

    def run(placed):
        return [{"index": i, "success": p == 2, "reasonable": p, "k": 2}
                for i, p in enumerate(placed)]  # fmt: skip

    gain = paired_gain(run([2, 1, 1, 0]), run([1, 1, 1]))
    assert gain["episodes"] == 3
    assert gain["placed"]["difference"] == pytest.approx(0.5 / 3, abs=1e-4)
    assert gain["placed"]["better"] == 1 and gain["placed"]["worse"] == 0
    assert gain["success"]["ci95"][0] >= 0


def test_a_fork_with_the_best_choice_replays_its_base(small_dataset, tmp_path):
    # the method's premise: the same seed gives the same episode, so a pair differs only by
    # its one choice (played in worker processes, as training plays them)
    from maniskill_tidy.knowledge import load_catalog
    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import MemoryPointer
    from maniskill_tidy.policies.memory_candidates import CONTEXT, KINDS, NUMERIC
    from maniskill_tidy.training.memory_forks import choose_forks
    from maniskill_tidy.training.memory_reinforce import _save_policy, play_jobs

    torch.manual_seed(0)  # an untrained pointer: it chooses badly, so choices matter
    sizes = {"kinds": len(KINDS), "receptacles": len(load_catalog().receptacles),
             "numeric": len(NUMERIC), "context": len(CONTEXT)}  # fmt: skip
    policy = tmp_path / "policy.pt"
    pointer = MemoryPointer(type_vectors(), **sizes)
    _save_policy(pointer, sizes, policy)
    config = memory_config(tmp_path, small_dataset, workers=2)
    cfg = MemoryConfig.load(config)
    mode = {"gamma": 0.99, "bonus": 1.0}
    bases = play_jobs(cfg, config, "I", "train", [(i, str(policy), {**mode, "keep": True})
                                                   for i in (0, 1)], "", False)  # fmt: skip
    base = bases[0]
    assert len(base["slot"]) > 5 and set(base["agent"].tolist()) == {0, 1, 2}
    (agent, n, other), *_ = choose_forks(pointer, base, 1, 2.0, np.random.default_rng(0))
    row = int(np.flatnonzero((base["agent"] == agent) & (base["n"] == n))[0])
    keep = {**mode, "keep": True}
    same, fork = play_jobs(cfg, config, "I", "train",
                           [(0, str(policy), {**keep, "override": (agent, n, base["slot"][row])}),
                            (0, str(policy), {**keep, "override": (agent, n, other)})],
                           "", False)  # fmt: skip
    keys = ("return", "success", "reasonable", "length", "slot", "agent", "n")
    assert all(np.array_equal(same[k], base[k]) for k in keys)
    # the fork is its base up to that decision, where the agent took the other candidate
    at = int(np.flatnonzero((fork["agent"] == agent) & (fork["n"] == n))[0])
    assert at == row and fork["slot"][at] == other != base["slot"][row]
    assert np.array_equal(fork["slot"][:row], base["slot"][:row])
    assert all(np.array_equal(fork[k][:row], base[k][:row]) for k in INPUTS)


def test_forks_fine_tune_the_clone_and_a_rerun_resumes(small_dataset, tmp_path, monkeypatch):
    from maniskill_tidy.training import memory_forks
    from maniskill_tidy.training.memory_trainer import train_memory

    # two of everything, so that every part plays in worker processes (no renderer here)
    forks = "{iterations: 1, episodes: 2, forks: 2, epochs: 2, val_episodes: 2}"
    two = "{starts: 1, tasks: 1, houses: 2}"
    cfg = memory_config(tmp_path, small_dataset, "fk", workers=2, forks=forks,
                        train_demos=two, val_demos=two)  # fmt: skip
    card = train_memory(cfg, "I", progress=False)
    part = card["forks"]
    assert part["rounds"] == 1 and part["curve"][0]["forks"] <= 4
    assert part["val_gain"]["episodes"] == 2 and part["kept"] in ("cloned", "last")
    folder = tmp_path / "fk" / "setting_I"
    assert (folder / "forks.png").read_bytes()[:4] == b"\x89PNG"
    assert "forked episodes" in (folder / "MODEL_CARD.md").read_text()
    weights = torch.load(folder / "model.pt", weights_only=False)["state"]

    def nothing_to_play(*args, **kwargs):
        raise AssertionError("a finished run played again")

    play_jobs = memory_forks.play_jobs
    monkeypatch.setattr(memory_forks, "play_jobs", nothing_to_play)
    again = train_memory(cfg, "I", progress=False)["forks"]
    assert again["curve"] == part["curve"] and again["val_gain"] == part["val_gain"]
    resumed = torch.load(folder / "model.pt", weights_only=False)["state"]
    assert all(torch.equal(weights[k], resumed[k]) for k in weights)

    # one more round continues the run, and its last round is judged on val again
    played: list[str] = []

    def counted(*args):
        played.append(args[5])  # the progress bar's label
        return play_jobs(*args)

    monkeypatch.setattr(memory_forks, "play_jobs", counted)
    more = cfg.read_text().replace("iterations: 1", "iterations: 2")
    cfg.write_text(more)
    longer = train_memory(cfg, "I", progress=False)["forks"]
    assert longer["rounds"] == 2 and longer["curve"][0] == part["curve"][0]
    assert played[0] == "bases, round 1" and "val, last" in played
    assert "val, cloned" not in played  # the clone's val run is kept


def test_a_forks_config_with_unknown_keys_or_two_later_stages_is_refused(small_dataset, tmp_path):
    with pytest.raises(ValueError, match="unknown forks keys \\['rounds'\\]; expected some of"):
        MemoryConfig.load(memory_config(tmp_path, small_dataset, forks="{rounds: 3}"))
    with pytest.raises(ValueError, match="both reinforce and forks; expected at most one"):
        MemoryConfig.load(memory_config(tmp_path, small_dataset, forks="{iterations: 1}",
                                        reinforce="{iterations: 1}"))  # fmt: skip
