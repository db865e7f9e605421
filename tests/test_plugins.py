"""A team written outside the package plays from its own folder: by import path, through a
config that names it, and as an installed package's entry point, with worker processes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.test_cli_errors import cli, one_line_error

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture
def folder(tmp_path):
    for name in ("wanderer.py", "wanderer.yaml"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    return tmp_path


def _summary(out: Path, name: str) -> dict:
    """A run's summary; a team without learned weights plays the default look (row NAME-v2)."""
    return json.loads((out / "eval/results/setting_I" / name / "summary.json").read_text())


def test_a_team_by_import_path_plays_with_two_workers(folder):
    p = cli("eval", "--policy", "wanderer:WandererTeam", "--setting", "I", "--episodes", "2",
            "--workers", "2", "--out", "out", cwd=folder)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    s = _summary(folder / "out", "wanderer-v2")
    assert s["episodes"] == 2 and s["workers"] == 2 and s["obs_mode"] == "none"


def test_a_team_by_import_path_plays_on_ray_actors(folder):
    pytest.importorskip("ray")
    p = cli("eval", "--policy", "wanderer:WandererTeam", "--setting", "I", "--episodes", "2",
            "--workers", "2", "--ray", "--out", "out", cwd=folder)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    s = _summary(folder / "out", "wanderer-v2")
    assert s["episodes"] == 2 and s["ray"]


def test_a_config_names_its_team_and_its_options(folder, monkeypatch):
    from maniskill_tidy.envs.actions import Action
    from maniskill_tidy.policies import make_team

    monkeypatch.chdir(folder)
    team = make_team("wanderer.yaml")
    assert team.name == "wanderer-right" and team.turn == Action.RotateRight
    assert make_team("wanderer:WandererTeam").turn == Action.RotateLeft
    (folder / "bad.yaml").write_text("team_class: wanderer:WandererTeam\noptions: {speed: 2}\n")
    with pytest.raises(ValueError, match="unexpected keyword argument 'speed'"):
        make_team("bad.yaml")


def test_an_installed_packages_team_is_found_by_its_entry_point(folder):
    dist = folder / "myteams-0.1.dist-info"  # what pip writes for a package declaring it
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: myteams\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[maniskill_tidy.teams]\nwander = wanderer:WandererTeam\n"
    )
    env = {"PYTHONPATH": str(folder)}
    p = cli("eval", "--policy", "wander", "--setting", "I", "--episodes", "1", "--out", "out",
            cwd=folder, env=env)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    assert _summary(folder / "out", "wanderer-v2")["episodes"] == 1


@pytest.mark.parametrize(
    "policy, words",
    [("nomodule:Team", ["no module 'nomodule'", "package.module:TeamClass"]),
     ("wanderer:Nope", ["wanderer has no Team class 'Nope'"]),
     ("wanderer:Wanderer", ["no Team class 'Wanderer'"]),  # an Agent, not a Team
     (":Team", ["expected package.module:TeamClass"])],
)  # fmt: skip
def test_a_bad_import_path_is_refused_in_one_line(folder, policy, words):
    p = cli("eval", "--policy", policy, "--setting", "I", "--episodes", "1", "--out", "out",
            cwd=folder)  # fmt: skip
    one_line_error(p, *words)
    assert not (folder / "out").exists()


def test_the_docs_talker_sends_and_is_counted(folder):
    p = cli("eval", "--policy", "wanderer:TalkerTeam", "--setting", "I", "--episodes", "1",
            "--out", "out", cwd=folder)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    m = _summary(folder / "out", "talker-v2")["metrics"]["All"]
    assert m["ACm"] == pytest.approx(6.0)  # three floats to each of two teammates, every step
