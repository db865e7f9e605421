"""The learned communication baselines: what each sends, that evaluation computes what training
does, and that each plays legally through the runner."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from maniskill_tidy.eval.episode import play_episode
from maniskill_tidy.eval.runner import RunConfig, make_env
from maniskill_tidy.models.communication import SCHEMES
from maniskill_tidy.models.communication.base import exchange
from maniskill_tidy.models.communication.cond import MISPLACED
from maniskill_tidy.models.decision import DecisionConfig, TeamDecision
from maniskill_tidy.policies import make_team
from maniskill_tidy.policies.agent_config import AgentConfig
from maniskill_tidy.policies.channel import CENTRAL, Channel, Outbox
from maniskill_tidy.policies.message_exchange import LearnedCentral, MessageExchange
from tests.conftest import taken_action

N = 3
MESSAGE = {"broadcast": 410, "cond": 410, "cmpr": 110, "inten": 10}
STEPS = 15


def _inputs(rng: np.random.Generator, n: int = N, mis=None) -> list[dict[str, torch.Tensor]]:
    """One step's inputs (1, 1, ·) of n agents."""
    out = []
    for i in range(n):

        def f(*shape):
            return torch.from_numpy(rng.normal(size=(1, 1, *shape)).astype(np.float32))

        out.append(dict(
            sv=f(256), sm=f(256), fd=f(256), fp=f(256), failed=torch.zeros(1, 1),
            mis=torch.tensor([[mis[i] if mis is not None else rng.random()]], dtype=torch.float32),
            det=torch.ones(1, 1), pose=f(4) * 3, va=torch.tensor([[[1.0, float(i > 0), 1.0]]]),
            held=torch.tensor([[-1]]), prev_task=torch.tensor([[[1, i, 2 * i, 0]]]),
        ))  # fmt: skip
    return out


@pytest.mark.parametrize("scheme", ["broadcast", "cond", "cmpr", "inten", "central"])
def test_evaluation_reads_the_messages_as_training_does(scheme):
    """Per-agent exchange over the counting channel = the team-level function trained."""
    torch.manual_seed(0)
    model = TeamDecision(DecisionConfig(communication=scheme), N).eval()
    x = _inputs(np.random.default_rng(1), mis=[0.9, 0.1, 0.7])
    present = torch.ones(1, 1, N, dtype=torch.bool)
    with torch.no_grad():
        inn, inter, _ = model._communicate(None, x, present, True, None)
    names = [f"agent_{i}" for i in range(N)]
    channel = Channel(names, central=scheme == "central")
    ex = [MessageExchange(a, Outbox(channel, a), model.agents[i].comm, 64, 64)
          for i, a in enumerate(names)]  # fmt: skip
    for e, xi in zip(ex, x, strict=True):
        e.send(0, xi)
    if scheme == "central":
        node = LearnedCentral(types_public(names), Outbox(channel, CENTRAL), model.central)
        node.send(0, channel.inbox(CENTRAL))
    for i, e in enumerate(ex):
        got_inn, got_inter = e.combine(channel.inbox(names[i]))
        assert torch.allclose(got_inn, inn[0, 0, i], atol=1e-5), (scheme, i)
        assert torch.allclose(got_inter, inter[0, 0, i], atol=1e-5), (scheme, i)
    dims = sorted(m.dims for m in channel.step_messages)
    if scheme == "central":
        assert dims == [64] * N + [410] * N
    elif scheme == "cond":  # agents 0 and 2 see a likely misplaced object, agent 1 does not
        assert {m.sender for m in channel.step_messages} == {"agent_0", "agent_2"}
        assert dims == [410] * 2 * (N - 1) and MISPLACED == 0.5
    else:
        assert dims == [MESSAGE[scheme]] * N * (N - 1)


def test_the_central_node_reads_teammates_sub_tasks_but_not_the_agents_own():
    """Its own last sub-task is the teacher's label in training: reading it teaches copying."""
    torch.manual_seed(0)
    model = TeamDecision(DecisionConfig(communication="central"), N).eval()
    planner = model.central
    x = _inputs(np.random.default_rng(2))
    up = torch.stack([a.comm.outgoing(xn) for a, xn in zip(model.agents, x, strict=True)], dim=2)
    present = torch.ones(1, 1, N, dtype=torch.bool)
    changed = up.clone()
    changed[0, 0, 1, 6:10] = torch.tensor([0.0, 5.0, 7.0, 1.0])  # agent 1's last sub-task
    with torch.no_grad():
        before, after = planner(up, present), planner(changed, present)
    assert torch.allclose(before[0, 0, 1], after[0, 0, 1])  # agent 1's own assignment
    assert not torch.allclose(before[0, 0, 0], after[0, 0, 0])  # a teammate's
    gone = present.clone()
    gone[0, 0, 2] = False  # an absent agent gets nothing and is not read
    with torch.no_grad():
        out = planner(up, gone)
        moved = up.clone()
        moved[0, 0, 2] += 1.0
        assert torch.all(out[0, 0, 2] == 0)
        assert torch.allclose(out, planner(moved, gone))


def types_public(names):
    from types import SimpleNamespace

    return SimpleNamespace(agents=names)  # the central node reads only the agents' names


def test_a_receiver_without_messages_gets_zeros_and_absent_agents_send_nothing():
    torch.manual_seed(0)
    model = TeamDecision(DecisionConfig(communication="cond"), N)
    x = _inputs(np.random.default_rng(2), mis=[0.1, 0.1, 0.9])
    present = torch.tensor([[[True, True, False]]])  # the only sender has stopped
    inn, inter, _ = model._communicate(None, x, present, True, None)
    assert inn.abs().sum() == 0 and inter.abs().sum() == 0


def test_cmpr_learns_to_decode_and_inten_to_predict_the_senders_sub_goal():
    torch.manual_seed(0)
    rng = np.random.default_rng(3)
    for scheme in ("cmpr", "inten"):
        model = TeamDecision(DecisionConfig(communication=scheme), N)
        messengers = [a.comm for a in model.agents]
        opt = torch.optim.Adam(model.parameters(), lr=3e-3)
        x = _inputs(rng)
        present = torch.ones(1, 1, N, dtype=torch.bool)
        ys = [{"dx": torch.tensor([[i + 2]]), "dy": torch.tensor([[6 - i]])} for i in range(N)]
        losses = []
        for _ in range(60):
            _, _, extras = exchange(messengers, x, present)
            loss = model.scheme.auxiliary_loss(messengers, x, extras, ys)
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(loss.item())
        assert losses[-1] < 0.2 * losses[0], (scheme, losses[0], losses[-1])
        if scheme == "inten":  # the labels are the senders': each receiver predicts them
            _, _, extras = exchange(messengers, x, present)
            intent = extras["pairs"][0]["intent"][0, 0]  # receiver 0 about senders 0..2
            assert intent[1, :9].argmax() == 3 and intent[2, 9:].argmax() == 4


def test_an_unknown_communication_is_refused_in_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nout: y\nmodel: {communication: telepathy}\n")
    with pytest.raises(ValueError, match="communication 'telepathy'.*expected one of"):
        AgentConfig.load(bad)


class Traffic:
    def start(self, env, team, channel) -> None:
        self.env, self.steps, self.illegal = env, [], []

    def decided(self, t, actions, labels) -> None:
        from maniskill_tidy.envs.actions import Action

        for a in self.env.agents:
            if a.name in actions:
                act = taken_action(a, actions[a.name])
                if not a.manipulator and act >= Action.PickUp:
                    self.illegal.append((t, a.name, act))
        self.active = sorted(actions)

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        self.steps.append((self.active, list(channel.step_messages)))


@pytest.fixture(scope="module")
def played(tmp_path_factory, seeded_config):
    root = tmp_path_factory.mktemp("variants")
    env = make_env(RunConfig("hangrcom", "I", "test", None, "standard"))
    env.unwrapped.max_steps = STEPS
    out = {}
    try:
        variants = {s: f"{{communication: {s}}}" for s in ("none", *MESSAGE, "central")}
        variants["wo_hierdec"] = "{hierarchical: false}"
        for scheme, model in variants.items():
            team = make_team(str(seeded_config(root, scheme, model, settings=(("I", N),))))
            traffic = Traffic()
            record = play_episode(env, team, 10, 10, [traffic])
            out[scheme] = (team, record, traffic)
    finally:
        env.close()
    return out


def test_each_variant_plays_legally_and_sends_what_it_is_specified_to(played):
    for scheme, (team, record, traffic) in played.items():
        assert not traffic.illegal, scheme
        if scheme == "wo_hierdec":  # its agents may choose Stop; HanGrCom's messages: test_teams
            assert 1 <= record.length <= STEPS and record.comm > 0
            continue
        assert record.length == STEPS, scheme
        assert team.communication == scheme and team.central == (scheme == "central")
        total = 0
        for active, messages in traffic.steps:
            total += sum(m.dims for m in messages)
            assert all(m.sender in active + [CENTRAL] for m in messages), scheme
            if scheme == "none":
                assert not messages
            elif scheme == "central":
                up = [m for m in messages if m.receiver == CENTRAL]
                down = [m for m in messages if m.sender == CENTRAL]
                assert sorted(m.sender for m in up) == active and {m.dims for m in up} == {410}
                assert sorted(m.receiver for m in down) == active
                assert {m.dims for m in down} == {64}
            elif scheme == "cond":
                for sender in {m.sender for m in messages}:
                    mine = [m for m in messages if m.sender == sender]
                    assert [m.dims for m in mine] == [410] * (N - 1)
            else:
                assert sorted(m.dims for m in messages) == [MESSAGE[scheme]] * (
                    len(active) * (N - 1)
                ), scheme
        assert record.comm == total, scheme


def test_the_ablations_cut_exactly_their_inputs():
    from maniskill_tidy.models.decision import StateExtractor

    rng = np.random.default_rng(4)
    x = _inputs(rng, n=1)[0]
    for option, cut, kept in (("misplaced_detector", ("fd", "mis"), "fp"),
                              ("receptacle_predictor", ("fp",), "fd")):  # fmt: skip
        torch.manual_seed(0)
        f = StateExtractor(DecisionConfig(**{option: False}))
        sf = f(x)[0]
        for key in cut:
            changed = {**x, key: x[key] + 1}
            assert torch.equal(f(changed)[0], sf), (option, key)
        assert not torch.equal(f({**x, kept: x[kept] + 1})[0], sf), option


def test_a_variant_config_states_only_what_it_changes(tmp_path):
    base = tmp_path / "base.yaml"
    base.write_text("name: b\nout: o\nmodel: {layout: true, mu: 0.3}\nact: {ope_threshold: 0.2}\n")
    (tmp_path / "v.yaml").write_text("base: base.yaml\nname: v\nmodel: {communication: cmpr}\n")
    v = AgentConfig.load(tmp_path / "v.yaml")
    assert (v.name, v.out, v.act) == ("v", "o", {"ope_threshold": 0.2})
    assert v.model == {"layout": True, "mu": 0.3, "communication": "cmpr"}
    base.write_text("base: v.yaml\nname: b\nout: o\n")
    with pytest.raises(ValueError, match="inherits from itself"):
        AgentConfig.load(tmp_path / "v.yaml")
    shipped = Path(__file__).resolve().parents[1] / "agents"
    from maniskill_tidy.policies.agent_config import load_config, trainer_of

    for path in sorted(shipped.glob("*.yaml")):  # every shipped variant loads
        if trainer_of(path) in ("qmix", "memory"):  # learners of their own, not variants
            assert load_config(path).out == f"agents/{path.stem}"
            continue
        cfg = AgentConfig.load(path)
        # an oracle acts with the model of the variant it names (SA(Oracle): the SA's)
        own = "agents/sa" if cfg.acting().oracle else f"agents/{path.stem}"
        assert cfg.out == own and cfg.decision().communication in SCHEMES


def test_the_learned_sa_plays_alone_in_every_setting(tmp_path, seeded_config):
    config = seeded_config(tmp_path, "sa", "{communication: none}", settings=(("I", 1),),
                           extra="team: [[1, 1, 1]]\n")  # fmt: skip
    for setting in ("I", "II"):
        team = make_team(str(config))
        assert team.team_override == [[1, 1, 1]]
        env = make_env(RunConfig(str(config), setting, "test", None, 1))
        env.unwrapped.max_steps = 5
        try:
            traffic = Traffic()
            record = play_episode(env, team, 0, 0, [traffic])
        finally:
            env.close()
        assert record.agents == 1 and record.comm == 0 and not traffic.illegal
    from maniskill_tidy.training.decision_trainer import train_decision

    with pytest.raises(ValueError, match="is trained with --setting I"):
        train_decision(config, "II", progress=False)


def test_a_scheme_is_a_registered_module_that_the_team_runs_without_branching(monkeypatch):
    """Adding a scheme is adding a class: a new message-passing scheme registered by name
    trains through TeamDecision and sends through the channel's MessageExchange unchanged."""
    from maniskill_tidy.models import communication
    from maniskill_tidy.models.communication.base import Messenger

    class Silent(Messenger):  # sends only from the first agent's position x < 0
        name, title, label = "silent", "test scheme", "silent communication"

        def sends(self, x):
            return x["pose"][..., 0] < 0

    monkeypatch.setitem(communication.SCHEMES, "silent", Silent)
    model = TeamDecision(DecisionConfig(communication="silent"), N)
    assert all(isinstance(a.comm, Silent) for a in model.agents)
    x = _inputs(np.random.default_rng(0))
    for n, xn in enumerate(x):
        xn["pose"] = torch.full_like(xn["pose"], 1.0 if n else -1.0)  # only agent 0 sends
    present = torch.ones(1, 1, N, dtype=torch.bool)
    inn, _, _ = model._communicate(None, x, present, True, None)
    assert inn[0, 0, 0].abs().sum() == 0  # agent 0 hears nobody
    sent = model.agents[0].comm.outgoing(x[0])
    for i in (1, 2):  # the others read agent 0's message alone, each with its own reader
        heard, _ = model.agents[i].comm.incoming(sent)
        assert torch.allclose(inn[0, 0, i], heard[0, 0])
