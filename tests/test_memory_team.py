"""The object-memory team: its candidates, its pointer, its training data and its trainer."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from maniskill_tidy.policies.agent_config import MemoryConfig


def memory_config(tmp_path: Path, dataset: Path, name: str = "mem", **extra) -> Path:
    fields = {"name": name, "out": str(tmp_path / name), "dataset": str(dataset),
              "work": str(tmp_path / "work"), "train_demos": "{starts: 1, tasks: 1, houses: 1}",
              "val_demos": "{starts: 1, tasks: 1, houses: 1}", "train": "{epochs: 3}",
              "val_episodes": 0, **extra}  # fmt: skip
    path = tmp_path / f"{name}.yaml"
    path.write_text("trainer: memory\n" + "".join(f"{k}: {v}\n" for k, v in fields.items()))
    return path


def test_recording_plays_as_the_teacher_and_every_choice_is_a_candidate(small_dataset, tmp_path):
    from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.policies.memory import memory_team_class
    from maniskill_tidy.policies.memory_candidates import KINDS, SLOTS

    recording = memory_team_class(memory_config(tmp_path, small_dataset))(recording=True)
    env = make_env(RunConfig("heuristic-detection", "I", "train", str(small_dataset)))
    try:
        teacher = run_episode(env, make_team("heuristic-detection"), 0, 0).to_dict()
        recorded = run_episode(env, recording, 0, 0).to_dict()
    finally:
        env.close()
    teacher.pop("seconds"), recorded.pop("seconds")
    assert recorded == teacher  # keeping the candidates changes nothing the team does
    decisions = [d for a in recording.made for d in a.decisions]
    assert len(decisions) > 10
    for _, rows, slot in decisions:
        n = int((rows.kind >= 0).sum())
        assert slot is not None and 0 <= slot < n <= SLOTS
        assert (rows.kind[:n] >= 0).all() and (rows.kind[n:] == -1).all()  # padding at the end
        assert rows.kind[n - 1] == KINDS.index("park")  # stopping is always a candidate
    manipulator = recording.made[2]  # Setting I: low scout, high scout, manipulator
    kinds = {KINDS[int(r.kind[s])] for _, r, s in manipulator.decisions}
    assert {"fetch", "place"} <= kinds  # it tidied something, so it chose both


def _play_explore_episode(config: str, dataset: str, start: str) -> dict:
    """The teacher's episode, then the recording's with ``_explore_cells`` watched: in a
    worker process, since renderers made in pytest's own one crash it (conftest)."""
    from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode
    from maniskill_tidy.policies import make_team
    from maniskill_tidy.policies.memory import memory_team_class
    from maniskill_tidy.policies.memory_candidates import MemoryCandidates

    explore_cells, seen = MemoryCandidates._explore_cells, []

    def kept(agent, avoid, dist):  # the cells, beside the same rule written as a plain loop
        cells = explore_cells(agent, avoid, dist)
        rows, cols, order = agent._unsearched(avoid, dist)
        rooms, want = agent._rooms(), []
        for i in order:
            cell = (int(rows[i]), int(cols[i]))
            if not want or (rooms[cell] >= 0 and rooms[cell] not in {rooms[c] for c in want}):
                want.append(cell)  # the heuristic's own cell, then each other room's first
        seen.append((cells, want[:3]))
        return cells

    MemoryCandidates._explore_cells = kept  # this worker ends with the test
    recording = memory_team_class(config)(recording=True)
    env = make_env(RunConfig("heuristic-detection", "I", "train", dataset))
    i = [e.id for e in env.unwrapped.episodes.episodes].index(start)
    try:
        teacher = run_episode(env, make_team("heuristic-detection"), i, i).to_dict()
        recorded = run_episode(env, recording, i, i).to_dict()
    finally:
        env.close()
    teacher.pop("seconds"), recorded.pop("seconds")
    rooms = recording.made[0]._rooms()
    decisions = [(rows, slot) for a in recording.made for _, rows, slot in a.decisions]
    return {"teacher": teacher, "recorded": recorded, "seen": seen, "decisions": decisions,
            "rooms": len(set(rooms[rooms >= 0].tolist()))}  # fmt: skip


def test_explore_candidates_in_other_rooms_leave_the_teacher_and_its_choice_alone(
    small_dataset, tmp_path
):
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from maniskill_tidy.policies.memory_candidates import KINDS, NUMERIC, ROOM_NUMERIC, slots

    config = memory_config(tmp_path, small_dataset, explore=3)
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        args = str(config), str(small_dataset), "house_00004/task_0/start_0"  # six rooms
        played = pool.submit(_play_explore_episode, *args).result()
    assert played["recorded"] == played["teacher"]
    assert played["rooms"] == 6
    for cells, want in played["seen"]:
        assert cells == want
    explore = KINDS.index("explore")
    assert played["decisions"]
    for rows, slot in played["decisions"]:
        assert rows.kind.shape == (slots(3),)
        assert rows.numeric.shape == (slots(3), len(NUMERIC) + len(ROOM_NUMERIC))
        at = [i for i in range(len(rows.kind)) if rows.kind[i] == explore]
        if rows.kind[slot] == explore:
            assert slot == at[0]  # the teacher took the heuristic's cell
        unsearched = rows.numeric[at, len(NUMERIC)]
        assert ((0 < unsearched) & (unsearched <= 1)).all()  # each has a cell to search
    assert max(len(cells) for cells, _ in played["seen"]) == 3


def test_the_pointer_ignores_padding_and_never_points_at_it():
    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import MemoryPointer

    torch.manual_seed(0)
    model = MemoryPointer(type_vectors(), kinds=6, receptacles=10, numeric=9, context=10).eval()
    g = torch.Generator().manual_seed(1)
    kind = torch.tensor([[0, 0, 3, 5]])
    types = torch.randint(0, 5, (1, 4), generator=g)
    rest = torch.randint(0, 11, (1, 4), generator=g)
    numeric, context = torch.rand(1, 4, 9, generator=g), torch.rand(1, 10, generator=g)
    pad = torch.full((1, 3), -1)
    with torch.no_grad():
        short = model(kind, types, rest, numeric, context)
        long = model(torch.cat([kind, pad], 1), torch.cat([types, pad.abs()], 1),
                     torch.cat([rest, pad.abs()], 1), torch.cat([numeric, torch.rand(1, 3, 9)], 1),
                     context)  # fmt: skip
    assert torch.allclose(long[0, :4], short[0], atol=1e-5)
    assert torch.isinf(long[0, 4:]).all() and int(long.argmax()) < 4


def test_a_kind_bias_moves_only_that_kinds_scores_and_never_revives_padding():
    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import KindBias, MemoryPointer

    torch.manual_seed(0)
    model = MemoryPointer(type_vectors(), kinds=6, receptacles=10, numeric=9, context=10).eval()
    kind = torch.tensor([[0, 3, 3, 5, -1]])
    types, rest = torch.zeros(1, 5, dtype=torch.long), torch.zeros(1, 5, dtype=torch.long)
    numeric, context = torch.rand(1, 5, 9), torch.rand(1, 10)
    biased = KindBias(model, [0.0, 0.0, 0.0, 50.0, 0.0, -1.0])
    with torch.no_grad():
        plain, moved = (
            model(kind, types, rest, numeric, context),
            biased(kind, types, rest, numeric, context),
        )
    assert torch.allclose(moved[0, :4] - plain[0, :4], torch.tensor([0.0, 50.0, 50.0, -1.0]))
    assert torch.isinf(moved[0, 4]) and int(moved.argmax()) in (1, 2)  # an explore, never padding


def test_memory_trains_seeded_and_its_team_plays(small_dataset, tmp_path):
    from maniskill_tidy.training.memory_trainer import train_memory

    first = memory_config(tmp_path, small_dataset, "a", val_episodes=1)
    card = train_memory(first, "I", progress=False)
    manifest = card["data"]["train"]
    assert manifest["rows"] > 10 and manifest["unmatched"] == 0
    assert card["val"]["by_kind"] and 0 <= card["val"]["balanced"] <= 1
    played = card["closed_loop"]
    assert played["student"]["episodes"] == played["teacher"]["episodes"] == 1
    folder = tmp_path / "a" / "setting_I"
    assert (folder / "curve.png").read_bytes()[:4] == b"\x89PNG"
    assert "behaviour cloning" in (folder / "MODEL_CARD.md").read_text()
    (tmp_path / "work" / "setting_I" / "pointer.ckpt").unlink()  # the same data, trained again
    again = train_memory(memory_config(tmp_path, small_dataset, "b"), "I", progress=False)
    assert again["data"]["train"]["data_hash"] == manifest["data_hash"]
    a = torch.load(folder / "model.pt", weights_only=False)["state"]
    b = torch.load(tmp_path / "b" / "setting_I" / "model.pt", weights_only=False)["state"]
    assert all(torch.equal(a[k], b[k]) for k in a)  # same seed, same data: the same weights
    rooms = memory_config(tmp_path, small_dataset, "c", explore=2)
    with pytest.raises(ValueError, match="other settings \\(explore\\)"):
        train_memory(rooms, "I", progress=False)  # its rows do not mix with explore 1's


def test_a_pointer_with_explore_candidates_trains_and_plays(small_dataset, tmp_path):
    from maniskill_tidy.policies import team_class
    from maniskill_tidy.policies.memory_candidates import NUMERIC, ROOM_NUMERIC
    from maniskill_tidy.training.memory_trainer import train_memory

    config = memory_config(tmp_path, small_dataset, "rooms", explore=3, val_episodes=1)
    card = train_memory(config, "I", progress=False)
    assert card["data"]["train"]["explore"] == 3 and card["data"]["train"]["unmatched"] == 0
    assert card["closed_loop"]["student"]["episodes"] == 1
    saved = torch.load(tmp_path / "rooms" / "setting_I" / "model.pt", weights_only=False)
    assert saved["sizes"]["numeric"] == len(NUMERIC) + len(ROOM_NUMERIC)
    team = ((1, 0, 0), (1, 0, 1), (1, 1, 1))
    assert team_class(str(config)).missing_model(team) is None
    for other in (1, 2):  # the same weights under a config with other candidates
        changed = memory_config(tmp_path, small_dataset, "rooms", explore=other)
        why = team_class(str(changed)).missing_model(team)
        assert f"trained with explore 3, where the config asks for {other}; train it" in why


def test_a_bad_memory_config_is_refused_in_one_line(tmp_path, small_dataset):
    from maniskill_tidy.policies import POLICIES, team_class
    from maniskill_tidy.policies.memory import MemoryTeam

    shipped = team_class("agents/memory.yaml")
    assert issubclass(shipped, MemoryTeam)
    assert shipped.communication == POLICIES["memory"].communication == "detection"
    with pytest.raises(ValueError, match="teacher 'heuristic-central': expected one of"):
        MemoryConfig.load(memory_config(tmp_path, small_dataset, teacher="heuristic-central"))
    with pytest.raises(ValueError, match="unknown model or train keys \\['width'\\]"):
        MemoryConfig.load(memory_config(tmp_path, small_dataset, model="{width: 3}"))
    with pytest.raises(ValueError, match="unknown reinforce keys \\['steps'\\]; expected some of"):
        MemoryConfig.load(memory_config(tmp_path, small_dataset, reinforce="{steps: 3}"))
    for explore in (0, 7, 2.5):
        with pytest.raises(ValueError, match=f"explore {explore}; expected a whole number from 1"):
            MemoryConfig.load(memory_config(tmp_path, small_dataset, explore=explore))
    untrained = team_class(str(memory_config(tmp_path, small_dataset, "untrained")))
    why = untrained.missing_model(((1, 0, 0), (1, 0, 1), (1, 1, 1)))
    assert "model.pt not found (looked in" in why and "train it with `maniskill-tidy train" in why


def test_the_team_return_is_discounted_and_shared_per_step():
    from maniskill_tidy.training.memory_reinforce import returns

    # 2 misplaced objects: one put where it belongs after step 1, the other after step 3
    g = returns([0, 0, 1, 1, 2], k=2, success=True, gamma=0.5, bonus=1.0)
    assert g.tolist() == pytest.approx([0.4375, 0.875, 0.75, 1.5])
    assert returns([0, 0, 1, 1, 1], k=2, success=False, gamma=0.5, bonus=1.0).tolist() == (
        pytest.approx([0.25, 0.5, 0.0, 0.0])
    )


def _batch(n: int = 512):
    """Decisions over (fetch, explore, park) where only choosing the fetch paid."""
    g = torch.Generator().manual_seed(2)
    slot = torch.randint(0, 3, (n,), generator=g)
    return {
        "kind": torch.tensor([[0, 3, 5, -1]]).repeat(n, 1),
        "type": torch.full((n, 4), 4),
        "rest": torch.full((n, 4), 10),
        "numeric": torch.rand(n, 4, 9, generator=g),
        "context": torch.rand(n, 10, generator=g),
        "slot": slot,
        "logp": torch.full((n,), -1.0986),  # drawn uniformly
        "ret": (slot == 0).float(),
    }


def test_ppo_moves_the_pointer_towards_what_paid_and_the_kl_term_holds_it_back():
    import copy

    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import MemoryPointer
    from maniskill_tidy.policies.agent_config import MemoryConfig
    from maniskill_tidy.training.memory_reinforce import Critic, ppo_update

    torch.manual_seed(0)
    cloned = MemoryPointer(type_vectors(), kinds=6, receptacles=10, numeric=9, context=10)
    data = _batch()
    rows = [data[k] for k in ("kind", "type", "rest", "numeric", "context")]

    def fetch_probability(kl: float) -> float:
        policy, critic = copy.deepcopy(cloned), Critic(cloned)
        optimisers = (torch.optim.Adam(policy.parameters(), lr=3e-3),
                      torch.optim.Adam(critic.parameters(), lr=1e-3))  # fmt: skip
        r = {**MemoryConfig.REINFORCE, "kl": kl, "epochs": 3, "batch": 128}
        stats = ppo_update(policy, critic, cloned, optimisers, data, r,
                           torch.Generator().manual_seed(0))  # fmt: skip
        assert stats["value_loss"] >= 0 and 0 <= stats["clipped"] <= 1
        with torch.no_grad():
            return float(torch.softmax(policy(*rows), -1)[:, 0].mean())

    with torch.no_grad():
        before = float(torch.softmax(cloned(*rows), -1)[:, 0].mean())
    free, held = fetch_probability(0.0), fetch_probability(20.0)
    assert free > before + 0.1
    assert before - 0.02 < held < free


def test_drawn_choices_are_seeded_per_episode_and_agent(small_dataset, tmp_path):
    # played in worker processes, as training plays them (and so no renderer in this one)
    from maniskill_tidy.knowledge import load_catalog
    from maniskill_tidy.models.checkpoints import type_vectors
    from maniskill_tidy.models.memory_pointer import MemoryPointer
    from maniskill_tidy.policies.memory_candidates import CONTEXT, KINDS, NUMERIC
    from maniskill_tidy.training.memory_reinforce import _play_all, _save_policy

    torch.manual_seed(0)  # an untrained pointer: its choices are far from certain
    sizes = {"kinds": len(KINDS), "receptacles": len(load_catalog().receptacles),
             "numeric": len(NUMERIC), "context": len(CONTEXT)}  # fmt: skip
    policy = tmp_path / "policy.pt"
    _save_policy(MemoryPointer(type_vectors(), **sizes), sizes, policy)
    config = memory_config(tmp_path, small_dataset, workers=2)
    cfg, r = MemoryConfig.load(config), MemoryConfig.REINFORCE

    def drawn(seed):
        played = _play_all(cfg, config, "I", "train", [0, 1], policy, seed, r, "", False)
        return [(e["slot"].tolist(), e["logp"].round(6).tolist()) for e in played]

    first, again, other = drawn(5), drawn(5), drawn(6)
    assert first == again and first != other
    assert all(slots for slots, _ in first) and sum(len(slots) for slots, _ in first) > 5
    assert all(lp <= 0 for _, logps in first for lp in logps)


def test_ppo_fine_tunes_the_clone_and_a_rerun_resumes(small_dataset, tmp_path, monkeypatch):
    from maniskill_tidy.training import memory_reinforce
    from maniskill_tidy.training.memory_trainer import train_memory

    # two of everything, so that every part plays in worker processes (no renderer here)
    ppo = "{iterations: 1, episodes: 2, epochs: 1, val_every: 1, val_episodes: 2}"
    two = "{starts: 1, tasks: 1, houses: 2}"
    cfg = memory_config(tmp_path, small_dataset, "ppo", workers=2, reinforce=ppo,
                        train_demos=two, val_demos=two)  # fmt: skip
    card = train_memory(cfg, "I", progress=False)
    part = card["reinforce"]
    assert part["rounds"] == 1 and [v["round"] for v in part["val"]] == [0, 1]
    assert part["curve"][0]["decisions"] > 0 and part["curve"][0]["episodes"] == 2
    assert part["best"]["placed"] >= part["cloned_val"]["placed"]  # round 0 is the clone
    folder = tmp_path / "ppo" / "setting_I"
    assert (folder / "reinforce.png").read_bytes()[:4] == b"\x89PNG"
    assert "then PPO on the team's return" in (folder / "MODEL_CARD.md").read_text()
    weights = torch.load(folder / "model.pt", weights_only=False)["state"]

    def nothing_to_play(*args, **kwargs):
        raise AssertionError("a finished run played again")

    monkeypatch.setattr(memory_reinforce, "_play_all", nothing_to_play)
    again = train_memory(cfg, "I", progress=False)["reinforce"]
    assert again["curve"] == part["curve"] and again["best"] == part["best"]
    resumed = torch.load(folder / "model.pt", weights_only=False)["state"]
    assert all(torch.equal(weights[k], resumed[k]) for k in weights)
