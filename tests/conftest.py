"""Shared fixtures.

A test that plays episodes through training code (``train_memory``, the PPO stage) should give
its config ``workers: 2`` and two jobs or more, so that they play in worker processes: with
the renderers of two such tests made and closed in pytest's own process, the suite died with
a segmentation fault two files later, in test_every_team_plays_a_whole_episode (twice).
"""

from pathlib import Path

import pytest

from maniskill_tidy.tasks.dataset import generate_dataset

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"
DATA = Path(__file__).parent / "data"


def taken_action(agent, action):
    """The Action an env agent's (possibly targeted) action is, after the env's own check
    (``parse_action`` raises on one the agent cannot take)."""
    from maniskill_tidy.envs.actions import Action, Targeted, parse_action

    parse_action(action, agent.n_actions, agent.name)
    return action.action if isinstance(action, Targeted) else Action(int(action))


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory) -> Path:
    """12 houses (8/2/2), seed 3: shared by tests that only read it."""
    out = tmp_path_factory.mktemp("ds") / "small"
    generate_dataset(out, 12, seed=3, progress=False)
    return out


def _seeded_config(
    root: Path, name: str, model: str, settings=(("I", 3), ("II", 4)), extra: str = ""
) -> Path:
    """An agent config whose decision models are freshly initialised from a seed: for the
    learned team's mechanics (perception, messages, executor), not what training taught it."""
    import torch

    from maniskill_tidy.models.checkpoints import save_decision
    from maniskill_tidy.models.decision import TeamDecision
    from maniskill_tidy.policies.agent_config import AgentConfig

    config = root / f"{name}.yaml"
    config.write_text(
        f"name: {name}\nout: {root / name}\nmodel: {model}\n"
        "act: {ope_threshold: 0.1, sample_subgoal: true}\n" + extra
    )
    cfg = AgentConfig.load(config)
    for setting, agents in settings:
        torch.manual_seed(0)
        save_decision(TeamDecision(cfg.decision(), agents), root / name / f"setting_{setting}", {})
    return config


@pytest.fixture(scope="session")
def learned_config(tmp_path_factory) -> Path:
    """The paper's model with every option on: the agents also run F_g's crop encoder, the goal
    channel, the thresholded operation and the sampled sub-goal."""
    root = tmp_path_factory.mktemp("learned")
    return _seeded_config(root, "hangrcom", "{layout: true, goal_map: true}")


@pytest.fixture(scope="session")
def seeded_config():
    """``seeded_config(root, name, model_yaml, settings)``: see :func:`_seeded_config`."""
    return _seeded_config


@pytest.fixture(scope="session")
def qmix_config(tmp_path_factory) -> Path:
    """A QMIX config whose Q-networks (Settings I and II) are freshly initialised from a seed."""
    import torch

    from maniskill_tidy.models.checkpoints import save_qmix
    from maniskill_tidy.models.qmix import QmixTeamModel

    root = tmp_path_factory.mktemp("qmix")
    config = root / "qmix.yaml"
    config.write_text(f"trainer: qmix\nname: qmix\nout: {root / 'qmix'}\n")
    for setting, agents in (("I", 3), ("II", 4)):
        torch.manual_seed(0)
        save_qmix(QmixTeamModel(agents), root / "qmix" / f"setting_{setting}",
                  {"perception": "agents/perception/knowledge"})  # fmt: skip
    return config
