from pathlib import Path

import pytest

from maniskill_tidy.tasks.dataset import generate_dataset

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory) -> Path:
    """12 houses (8/2/2), seed 3: shared by tests that only read it."""
    out = tmp_path_factory.mktemp("ds") / "small"
    generate_dataset(out, 12, seed=3, progress=False)
    return out


@pytest.fixture(scope="session")
def learned_config(tmp_path_factory) -> Path:
    """An agent config whose decision models (Settings I and II) are freshly initialised from
    a seed: it tests the learned team's mechanics (perception, HanGrCom's messages, executor),
    not what training taught it."""
    import torch

    from maniskill_tidy.training.decision_trainer import AgentConfig, save_model

    root = tmp_path_factory.mktemp("learned")
    config = root / "hangrcom.yaml"
    # every option on: the agents also run F_g's crop encoder, the goal channel, the
    # thresholded operation and the sampled sub-goal
    config.write_text(
        f"name: hangrcom\nout: {root / 'hangrcom'}\nmodel: {{layout: true, goal_map: true}}\n"
        "act: {ope_threshold: 0.1, sample_subgoal: true}\n"
    )
    cfg = AgentConfig.load(config)
    for setting, agents in (("I", 3), ("II", 4)):
        from maniskill_tidy.models.decision import TeamDecision

        torch.manual_seed(0)
        save_model(
            TeamDecision(cfg.decision(), agents), root / "hangrcom" / f"setting_{setting}", {}
        )
    return config
