"""HanGrCom by hand: queries and keys whose T is known, the groups, inn, int and the dimensions
the paper's rules give; the soft (training) mode; the batched hard mode equals the agents'."""

import numpy as np
import pytest
import torch

from maniskill_tidy.models.hangrcom import attention, handshake, hard, soft
from maniskill_tidy.policies.channel import Channel, Outbox
from maniskill_tidy.policies.handshake_exchange import HandshakeExchange

# T by hand. Agents 0 and 1 ask (T_ii < 0.8) and link to each other (> 0.2); agent 2 asks and
# links to 3; agent 3 does not ask. Groups {0, 1} and {2, 3} (the paper's Fig. 5).
W = np.array(
    [
        [0.50, 0.40, 0.02, 0.08],
        [0.30, 0.60, 0.05, 0.05],
        [0.15, 0.05, 0.50, 0.30],
        [0.05, 0.05, 0.05, 0.85],
    ]
)
AGENTS = ["a0", "a1", "a2", "a3"]
D = 4  # query and key size: one-hot queries and log-weight keys give T = W


def gens(rng) -> list[dict[str, torch.Tensor]]:
    """qry_j = e_j and key_i = sqrt(d) log W_i: attc_ij = log W_ij, so softmax(row i) = W_i."""
    out = []
    for i in range(4):
        out.append(
            {
                "qry": torch.eye(D)[i],
                "key": torch.tensor(np.sqrt(D) * np.log(W[i]), dtype=torch.float32),
                "val": torch.tensor(rng.normal(size=6), dtype=torch.float32),
                "inv": torch.tensor(rng.normal(size=5), dtype=torch.float32),
            }
        )
    return out


def test_attention_of_hand_set_queries_and_keys_is_the_hand_computed_t():
    g = gens(np.random.default_rng(0))
    qry = torch.stack([x["qry"] for x in g])
    key = torch.stack([x["key"] for x in g])
    t = attention(qry, key, torch.ones(4, dtype=torch.bool))
    assert np.allclose(t.numpy(), W, atol=1e-6)


def test_handshake_gives_the_papers_groups_links_and_inter_group_agent():
    hs = handshake(W, np.ones(4, bool))
    assert hs.asks.tolist() == [True, True, True, False]
    links = {(int(i), int(j)) for i, j in zip(*np.nonzero(hs.links), strict=True)}
    assert links == {(0, 1), (1, 0), (2, 3)}  # (receiver, sender)
    assert hs.groups == [[0, 1], [2, 3]]
    # group {0, 1} attends to 3 (mean 0.065) more than 2 (0.035); group {2, 3} to 0 (0.1)
    assert hs.inter.tolist() == [3, 3, 0, 0]


def test_an_absent_agent_is_in_no_group_and_a_lone_group_gets_no_inter_vector():
    present = np.array([True, True, False, False])
    t = W.copy()
    t[:, 2:] = 0
    t[2:] = 0
    t[:2] /= t[:2].sum(1, keepdims=True)
    hs = handshake(t, present)
    assert hs.groups == [[0, 1]]
    assert hs.inter.tolist() == [-1, -1, -1, -1]


def run_exchange(g, channel: Channel, agents=AGENTS):
    ex = {a: HandshakeExchange(a, AGENTS, Outbox(channel, a), 0.2, 0.8) for a in agents}
    channel.new_step()
    for r in range(3):  # as eval/episode.py runs the rounds
        channel.round = r
        for a in agents:
            ex[a].send(r, channel.inbox(a, before_round=r), g[AGENTS.index(a)])
    return ex


def test_the_exchange_sends_what_the_rules_say_and_combines_inn_and_int():
    g = gens(np.random.default_rng(1))
    channel = Channel(AGENTS)
    ex = run_exchange(g, channel)
    val = [x["val"] for x in g]
    inv = [x["inv"] for x in g]
    expect_inn = {
        "a0": 0.5 * val[0] + 0.4 * val[1],
        "a1": 0.6 * val[1] + 0.3 * val[0],
        "a2": 0.5 * val[2] + 0.3 * val[3],
        "a3": 0.85 * val[3],
    }
    expect_int = {"a0": inv[3], "a1": inv[3], "a2": inv[0], "a3": inv[0]}
    for a in AGENTS:
        inn, inter = ex[a].combine(channel.inbox(a), g[AGENTS.index(a)])
        assert torch.allclose(inn, expect_inn[a], atol=1e-5), a
        assert torch.allclose(inter, expect_int[a]), a
        assert ex[a].groups() == [["a0", "a1"], ["a2", "a3"]]
    # queries 4 x 3 x 4, rows of T 4 x 3 x 4, values along 3 links x 6, inter vectors 4 x 5
    assert channel.total == 4 * 3 * D + 4 * 3 * 4 + 3 * 6 + 4 * 5
    kinds = {}
    for m in channel.step_messages:
        kinds[m.kind] = kinds.get(m.kind, 0) + m.dims
    assert kinds == {"query": 48, "attention": 48, "value": 18, "inter": 20}
    # and the batched hard mode the trainer uses gives the same vectors
    t = torch.tensor(W, dtype=torch.float32)
    inn, inter = hard(t, torch.stack(val), torch.stack(inv), torch.ones(4, dtype=torch.bool))
    for i, a in enumerate(AGENTS):
        assert torch.allclose(inn[i], expect_inn[a], atol=1e-5)
        assert torch.allclose(inter[i], expect_int[a])


def test_a_stopped_teammate_gets_no_more_messages():
    g = gens(np.random.default_rng(2))
    channel = Channel(AGENTS)
    ex = run_exchange(g, channel)
    channel.new_step()  # a3 has stopped: it neither sends nor is sent to after this step
    for r in range(3):
        channel.round = r
        for a in AGENTS[:3]:
            ex[a].send(r, channel.inbox(a, before_round=r), g[AGENTS.index(a)])
    assert all(m.receiver != "a3" for m in channel.step_messages if m.kind != "query")
    channel.new_step()
    for r in range(3):
        channel.round = r
        for a in AGENTS[:3]:
            ex[a].send(r, channel.inbox(a, before_round=r), g[AGENTS.index(a)])
    assert all(m.receiver != "a3" for m in channel.step_messages)
    assert all(len(ex[a].present) == 4 and not ex[a].present[3] for a in AGENTS[:3])


def test_soft_mode_is_the_papers_training_formulas_over_the_present_agents():
    rng = np.random.default_rng(3)
    val, inv = torch.randn(4, 6), torch.randn(4, 5)
    t = torch.tensor(W, dtype=torch.float32)
    inn, inter = soft(t, val, inv)
    assert torch.allclose(inn, t @ val, atol=1e-6)
    assert torch.allclose(inter, (1 - t) @ inv, atol=1e-6)
    # with agent 3 absent, it neither contributes nor receives
    present = torch.tensor([True, True, True, False])
    q, k = torch.tensor(rng.normal(size=(4, 3))), torch.tensor(rng.normal(size=(4, 3)))
    t = attention(q.float(), k.float(), present)
    assert torch.allclose(t.sum(-1), torch.tensor([1.0, 1.0, 1.0, 0.0]))
    assert float(t[:, 3].abs().sum()) == 0
    inn, inter = soft(t, val, inv)
    assert float(inn[3].abs().sum()) == 0 and float(inter[3].abs().sum()) == 0
    assert torch.allclose(inter[0], (1 - t[0, :3]) @ inv[:3], atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_batched_hard_mode_matches_the_exchange_on_random_t(seed):
    rng = np.random.default_rng(seed)
    g = []
    for _ in range(4):
        g.append({k: torch.tensor(rng.normal(size=n), dtype=torch.float32) * 2
                  for k, n in (("qry", 4), ("key", 4), ("val", 6), ("inv", 5))})  # fmt: skip
    channel = Channel(AGENTS)
    ex = run_exchange(g, channel)
    stack = {k: torch.stack([x[k] for x in g]) for k in g[0]}
    present = torch.ones(4, dtype=torch.bool)
    t = attention(stack["qry"], stack["key"], present)
    inn, inter = hard(t, stack["val"], stack["inv"], present)
    for i, a in enumerate(AGENTS):
        got_inn, got_int = ex[a].combine(channel.inbox(a), g[i])
        assert torch.allclose(got_inn, inn[i], atol=1e-5)
        assert torch.allclose(got_int, inter[i], atol=1e-6)
