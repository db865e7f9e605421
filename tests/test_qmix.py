"""QMIX: a monotonic mixer, TD targets, a resumable seeded training loop, and a team that sends
its state features and acts legally."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from maniskill_tidy.models.qmix import OBS, QmixTeamModel
from maniskill_tidy.policies.agent_config import QmixConfig
from maniskill_tidy.training.qmix_trainer import collate, td_loss, train_qmix


def test_the_mixer_is_monotonic_in_every_agents_q():
    torch.manual_seed(0)
    model = QmixTeamModel(3)
    for _ in range(20):
        chosen = torch.randn(16, 3, requires_grad=True)
        obs = torch.randn(16, 3, OBS)
        q_tot = model.mix(chosen, obs, torch.ones(16, 3, dtype=torch.bool))
        (grad,) = torch.autograd.grad(q_tot.sum(), chosen)
        assert (grad >= 0).all()
    chosen = torch.randn(4, 3)
    absent = torch.tensor([[True, False, True]] * 4)
    changed = chosen.clone()
    changed[:, 1] += 100.0
    obs = torch.randn(4, 3, OBS)
    assert torch.equal(model.mix(chosen, obs, absent), model.mix(changed, obs, absent))


def _episode(t: int, reward: float) -> dict:
    torch.manual_seed(t)
    actions = torch.randint(0, 8, (t, 2))
    return {"obs": torch.randn(t, 2, OBS).half(), "actions": actions,
            "legal": torch.ones(t, 2, 11, dtype=torch.bool), "present": actions >= 0,
            "reward": torch.full((t,), reward)}  # fmt: skip


def test_td_learns_the_return_of_a_one_step_episode_and_pads_to_the_longest():
    batch = collate([_episode(1, 1.0), _episode(3, 0.0)])
    assert batch["valid"].tolist() == [[True, False, False], [True, True, True]]
    assert (batch["actions"][0, 1:] == -1).all()
    torch.manual_seed(0)
    model = QmixTeamModel(2)
    target = QmixTeamModel(2)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    one = collate([_episode(1, 1.0)])
    for _ in range(200):
        loss = td_loss(model, target, one, 0.99)
        opt.zero_grad()
        loss.backward()
        opt.step()
    q = model.q_values(one["obs"].float(), one["present"])
    chosen = q.gather(-1, one["actions"].unsqueeze(-1)).squeeze(-1)
    q_tot = model.mix(chosen, one["obs"].float(), one["present"])
    assert q_tot.item() == pytest.approx(1.0, abs=0.05)  # terminal: the target is the reward


def test_qmix_trains_seeded_resumes_and_writes_its_card(small_dataset, tmp_path):
    def config(name: str, episodes: int) -> Path:
        path = tmp_path / f"{name}.yaml"
        val = 1 if name == "a" else 0  # val episodes are not part of training: checked once
        path.write_text(
            f"trainer: qmix\nname: {name}\nout: {tmp_path / name}\ndataset: {small_dataset}\n"
            f"work: {tmp_path / 'work' / name}\nepisodes: {episodes}\nmax_steps: 4\nbatch: 2\n"
            f"buffer: 2\nupdates: 1\ntarget_every: 1\nval_episodes: {val}\n"
            "epsilon: {start: 1.0, end: 0.0, episodes: 2}\n"
        )
        return path

    from maniskill_tidy.eval.runner import RunConfig, make_env

    env = make_env(RunConfig("qmix", "I", "train", str(small_dataset)))  # shared by the runs
    try:
        straight = train_qmix(config("a", 3), "I", progress=False, env=env)
        train_qmix(config("b", 2), "I", progress=False, env=env)  # stopped after two ...
        resumed = train_qmix(config("b", 3), "I", progress=False, env=env)  # ... and resumed
    finally:
        env.close()
    a = torch.load(tmp_path / "a" / "setting_I" / "model.pt", weights_only=False)["state"]
    b = torch.load(tmp_path / "b" / "setting_I" / "model.pt", weights_only=False)["state"]
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert [c["return"] for c in straight["curve"]] == [c["return"] for c in resumed["curve"]]
    assert straight["env_steps"] == sum(c["length"] for c in straight["curve"]) <= 12
    assert straight["curve"][0]["epsilon"] == 1.0 and straight["curve"][2]["epsilon"] == 0.0
    card = json.loads((tmp_path / "a" / "setting_I" / "card.json").read_text())
    assert card["val"]["episodes"][0]["length"] >= 1
    assert (tmp_path / "a" / "setting_I" / "curve.png").read_bytes()[:4] == b"\x89PNG"
    assert "team reward" in (tmp_path / "a" / "setting_I" / "MODEL_CARD.md").read_text()


def test_a_bad_qmix_config_is_refused_in_one_line(tmp_path):
    from maniskill_tidy.policies import team_class
    from maniskill_tidy.policies.qmix_team import QmixTeam

    shipped = team_class("agents/qmix.yaml")  # eval --policy agents/qmix.yaml
    assert issubclass(shipped, QmixTeam) and shipped.folder == Path("agents/qmix")
    bad = tmp_path / "q.yaml"
    bad.write_text("trainer: qmix\nname: q\nout: o\nreward: {placed: 1}\n")
    with pytest.raises(ValueError, match="reward needs placed, picked and step"):
        QmixConfig.load(bad)
    bad.write_text("trainer: qmix\nname: q\nout: o\nlearning: 3\n")
    with pytest.raises(ValueError, match="unknown keys \\['learning'\\]"):
        QmixConfig.load(bad)


def test_the_qmix_team_sends_its_state_feature_and_acts_legally(tmp_path, monkeypatch):
    from maniskill_tidy.envs.actions import Action, Targeted
    from maniskill_tidy.eval.episode import play_episode
    from maniskill_tidy.eval.runner import RunConfig, make_env
    from maniskill_tidy.models.checkpoints import save_qmix
    from maniskill_tidy.policies.qmix_team import QmixTeam

    torch.manual_seed(0)
    perception = {"perception": "agents/perception/knowledge"}
    save_qmix(QmixTeamModel(3), tmp_path / "setting_I", perception)
    monkeypatch.setattr(QmixTeam, "folder", tmp_path)

    class Check:
        def start(self, env, team, channel):
            self.env, self.bad, self.sent, self.expected = env, [], [], 0

        def decided(self, t, actions, labels):
            for a in self.env.agents:
                act = actions.get(a.name)
                if act is None:
                    continue
                act = act.action if isinstance(act, Targeted) else Action(int(act))
                if not a.manipulator and act >= Action.PickUp:
                    self.bad.append((t, a.name, act))
            self.active = len(actions)

        def log_step(self, t, obs, actions, info, channel, labels):
            dims = sorted(m.dims for m in channel.step_messages)
            self.sent.append(dims == [256] * self.active * 2)  # to both teammates
            self.expected += 256 * 2 * self.active

    env = make_env(RunConfig("qmix", "I", "test", None, 1))
    env.unwrapped.max_steps = 10
    check = Check()
    try:
        record = play_episode(env, QmixTeam(epsilon=0.0), 10, 10, [check])
    finally:
        env.close()
    assert not check.bad and check.sent and all(check.sent)
    assert record.comm == check.expected > 0


def test_a_qmix_config_inherits_from_its_base_like_every_agent_config(tmp_path):
    """One loader for every agent config: ``base:`` works for QMIX too, and the inherited
    ``trainer: qmix`` still makes it a QMIX config."""
    from maniskill_tidy.policies.agent_config import is_qmix_config, load_config

    shipped = Path(__file__).resolve().parents[1] / "agents" / "qmix.yaml"
    variant = tmp_path / "qmix-short.yaml"
    variant.write_text(f"base: {shipped}\nname: qmix-short\nout: {tmp_path / 'out'}\nepisodes: 3\n")
    cfg = load_config(variant)
    base = QmixConfig.load(shipped)
    assert is_qmix_config(variant) and isinstance(cfg, QmixConfig)
    assert (cfg.name, cfg.episodes) == ("qmix-short", 3)
    assert (cfg.gamma, cfg.buffer, cfg.reward) == (base.gamma, base.buffer, base.reward)
