"""The object-memory team with HanGrCom links carrying memory entries: labels, the link
model, the messages and the trainer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from test_memory_team import memory_config


@pytest.fixture(scope="module")
def pointer(small_dataset, tmp_path_factory) -> Path:
    """A pointer cloned on the small dataset: the folder a links config names (``pointer``)."""
    from maniskill_tidy.training.memory_trainer import train_memory

    tmp = tmp_path_factory.mktemp("pointer")
    train_memory(memory_config(tmp, small_dataset, "p"), "I", progress=False)
    return tmp / "p"


def snapshot(manipulator: bool, misplaced: dict | None = None, known=(), reports=(), told=None):
    return {"t": 0, "sf": None, "manipulator": manipulator, "known": set(known),
            "misplaced": misplaced or {}, "reports": list(reports), "told": told or {}}  # fmt: skip


def test_a_teammate_is_useful_to_a_manipulator_only_with_news():
    from maniskill_tidy.training.memory_links import useful_links

    names = ["scout", "arm"]
    cup = {"cup_1": ("Cup", 1.0, 2.0)}
    scout_knows = snapshot(False, cup)
    useful = useful_links(names, [scout_knows, snapshot(True)])
    assert useful.tolist() == [[False, False], [True, False]]
    # the arm saw the cup itself, was told of it, or has a report of it: no news
    assert not useful_links(names, [scout_knows, snapshot(True, known={"cup_1"})]).any()
    told = snapshot(False, cup, told={"arm": {"cup_1"}})
    assert not useful_links(names, [told, snapshot(True)]).any()
    reported = snapshot(True, reports=[("Cup", 1.2, 2.1)])
    assert not useful_links(names, [scout_knows, reported]).any()
    other_type = snapshot(True, reports=[("Book", 1.0, 2.0)])
    assert useful_links(names, [scout_knows, other_type])[1, 0]
    # a scout fetches nothing, and an agent that stopped is not asked
    assert not useful_links(names, [snapshot(False), snapshot(False, cup)]).any()
    assert not useful_links(names, [None, snapshot(True)]).any()


def test_a_link_carries_the_state_and_four_values_per_entry():
    from maniskill_tidy.policies.base import SubTask
    from maniskill_tidy.policies.memory_links import decode_entries, encode_entries
    from maniskill_tidy.policies.messages import encode_state

    state = encode_state((1, 1, 1), (2.5, -1.0, 90), SubTask("Place", "Cup", "", ""))
    v = encode_entries(state, [("Book", np.array([1.0, 2.0, 0.4])), ("Cup", (3.0, 4.0, 0.9))])
    assert v.shape == (10 + 2 * 4,)
    st, entries = decode_entries(v)
    assert st.capability == (1, 1, 1) and st.subtask.object_type == "Cup"
    assert entries == [("Book", (1.0, 2.0)), ("Cup", (3.0, 4.0))]
    assert decode_entries(encode_entries(state, []))[1] == []
    with pytest.raises(ValueError, match="10 \\+ 4 x k values, got 13"):
        decode_entries(v[:13])


def test_wanted_rows_share_the_useful_teammates_or_stay_on_oneself():
    from maniskill_tidy.models.memory_links import target_rows

    useful = torch.tensor([[[0, 1, 1], [0, 0, 0], [1, 0, 0]]], dtype=torch.bool)
    present = torch.tensor([[True, True, False]])
    wanted = target_rows(useful, present)[0]
    assert wanted[0].tolist() == [0.0, 1.0, 0.0]  # the absent third is no one's teammate
    assert wanted[1].tolist() == [0.0, 1.0, 0.0]  # nobody useful: it does not ask
    assert wanted[2].tolist() == [0.0, 0.0, 0.0]  # absent


def test_query_and_key_learn_who_should_ask_whom():
    """A rule the summary can express (a manipulator asks the teammates with untold objects)
    is learned, and the hard handshake then links exactly those pairs."""
    from maniskill_tidy.models.hangrcom import hard_links
    from maniskill_tidy.models.memory_links import MemoryLinks, link_loss, target_rows
    from maniskill_tidy.policies.memory_links import SUMMARY

    g = torch.Generator().manual_seed(0)
    n, steps = 3, 1024
    sf = torch.rand(steps, n, len(SUMMARY), generator=g)
    sf[..., 1] = (sf[..., 1] > 0.5).float()  # manipulation
    sf[..., 6] = torch.where(torch.rand(steps, n, generator=g) < 0.3, sf[..., 6] + 0.5, 0.0)
    useful = (sf[..., 1] > 0)[:, :, None] & (sf[..., 6] > 0)[:, None, :]
    present = torch.ones(steps, n, dtype=torch.bool)
    torch.manual_seed(0)
    model = MemoryLinks(len(SUMMARY))
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    wanted = target_rows(useful, present)
    for _ in range(1500):
        loss = link_loss(model.rows(sf, present), wanted, present.float())
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        links, _, _ = hard_links(model.rows(sf, present), present)
    truth = useful & ~torch.eye(n, dtype=torch.bool)
    assert (links & truth).sum() / truth.sum() > 0.9  # recall
    assert (links & truth).sum() / links.sum() > 0.9  # precision


def _play_with_every_link(config: str, dataset: str) -> dict:
    """One episode of a links team whose untrained (zero) generators make T uniform, so every
    agent asks and links to every teammate; what the channel carried. In a worker process,
    as renderers made in pytest's own one crash it (conftest)."""
    from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode
    from maniskill_tidy.models.memory_links import MemoryLinks
    from maniskill_tidy.policies.channel import Channel
    from maniskill_tidy.policies.memory import memory_team_class
    from maniskill_tidy.policies.memory_links import SUMMARY, LinkedMemoryAgent

    sent = []
    send = Channel.send

    def logged(self, sender, receivers, vector, kind):
        copies = 1 if isinstance(receivers, str) else len(receivers)
        sent.append((self.round, sender, kind, int(np.asarray(vector).size), copies))
        return send(self, sender, receivers, vector, kind)

    Channel.send = logged  # this worker ends with the test
    traced = []
    trace = LinkedMemoryAgent.trace

    def kept(self):
        out = trace(self)
        traced.append(out)
        return out

    LinkedMemoryAgent.trace = kept
    team = memory_team_class(config)(keep_decisions=True)
    zero = MemoryLinks(len(SUMMARY))
    for p in zero.parameters():
        torch.nn.init.zeros_(p)
    team.use_links("I", zero)
    env = make_env(RunConfig("heuristic-detection", "I", "train", dataset))
    try:
        record = run_episode(env, team, 0, 0).to_dict()
    finally:
        env.close()
    reports = sum(len(a.reports) + len(a.dismissed) for a in team.made)
    told = sum(len(s) for a in team.made for s in a.told.values())
    handshakes = [(np.shape(t["T"]), t["groups"]) for t in traced if "T" in t]
    return {"record": record, "sent": sent, "reports": reports, "told": told,
            "handshakes": handshakes}  # fmt: skip


def test_a_links_team_sends_only_the_handshake_and_entries_along_its_links(
    small_dataset, tmp_path, pointer
):
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from maniskill_tidy.policies.agent_config import MemoryConfig
    from maniskill_tidy.training.memory_links import copy_pointer

    links = memory_config(tmp_path, small_dataset, "l", links=f"{{pointer: {pointer}}}")
    copy_pointer(MemoryConfig.load(links), "I")  # what the links' training starts with
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        played = pool.submit(_play_with_every_link, str(links), str(small_dataset)).result()
    kinds = {(r, k) for r, _, k, _, _ in played["sent"]}
    assert kinds == {(0, "query"), (1, "attention"), (2, "value")}
    for _, _, kind, size, _ in played["sent"]:
        assert size == {"query": 8, "attention": 3}.get(kind, size)
        if kind == "value":
            assert size >= 10 and (size - 10) % 4 == 0 and size <= 10 + 4 * 4
    assert played["told"] > 0 and played["reports"] > 0  # entries went out and were taken in
    # recordings get each step's T and groups: with every link, one group of all three
    assert played["handshakes"] and all(shape == (3, 3) for shape, _ in played["handshakes"])
    assert any(len(groups) == 1 and len(groups[0]) == 3 for _, groups in played["handshakes"])
    assert played["record"]["comm"] == sum(size * copies for *_, size, copies in played["sent"])


def test_links_train_on_a_copied_pointer_and_resume(small_dataset, tmp_path, pointer):
    from maniskill_tidy.models.checkpoints import weights_digest
    from maniskill_tidy.policies import team_class
    from maniskill_tidy.training.memory_trainer import train_memory

    config = memory_config(tmp_path, small_dataset, "l", val_episodes=1,
                           links=f"{{pointer: {pointer}, epochs: 3}}")  # fmt: skip
    team = ((1, 0, 0), (1, 0, 1), (1, 1, 1))
    card = train_memory(config, "I", progress=False)
    train = card["data"]["train"]
    assert train["agent_steps"] > 100 and 0 < train["useful_share"] < 1
    assert 0 <= card["val"]["precision"] <= 1 and card["epochs"] <= 3
    assert card["closed_loop"]["student"]["episodes"] == 1
    folder = tmp_path / "l" / "setting_I"
    assert (folder / "curve.png").read_bytes()[:4] == b"\x89PNG"
    assert "memory entries over HanGrCom links" in (folder / "MODEL_CARD.md").read_text()
    saved = torch.load(tmp_path / "l" / "setting_I" / "model.pt", weights_only=False)
    cloned = torch.load(pointer / "setting_I" / "model.pt", weights_only=False)
    assert all(torch.equal(saved["state"][k], cloned["state"][k]) for k in cloned["state"])
    links = team_class(str(config))
    assert links.communication == "handshake" and links.rounds == 3
    assert links.missing_model(team) is None
    assert links.model_hash(team) != weights_digest(pointer / "setting_I")
    again = train_memory(config, "I", progress=False)  # the recorded houses are reused
    assert again["data"]["train"]["data_hash"] == train["data_hash"]
    assert again["data"]["train"]["seconds"] == train["seconds"]
    bare = memory_config(tmp_path, small_dataset, "bare", links=f"{{pointer: {pointer}}}")
    (tmp_path / "bare" / "setting_I").mkdir(parents=True)
    for f in ("model.pt", "card.json"):
        (tmp_path / "bare" / "setting_I" / f).write_bytes((pointer / "setting_I" / f).read_bytes())
    assert "holds a pointer without links" in team_class(str(bare)).missing_model(team)


def test_a_bad_links_section_is_refused_in_one_line(tmp_path, small_dataset):
    from maniskill_tidy.policies.agent_config import MemoryConfig

    bad = memory_config(tmp_path, small_dataset, "bad", links="{pointer: x, rounds: 2}")
    with pytest.raises(ValueError, match="unknown links keys \\['rounds'\\]"):
        MemoryConfig.load(bad)
    both = memory_config(tmp_path, small_dataset, "both", links="{pointer: x}",
                         forks="{iterations: 1}")  # fmt: skip
    with pytest.raises(ValueError, match="links with reinforce or forks"):
        MemoryConfig.load(both)
