"""Where learned teams' files are found: the working folder, $MANISKILL_TIDY_AGENTS, then the
agents the package ships (common/agent_files.py); a missing one says where it was looked for."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from maniskill_tidy.common import agent_files
from maniskill_tidy.common.agent_files import AGENTS_ENV, SHIPPED, candidates, resolve

REPO = Path(__file__).resolve().parents[1]


def test_shipped_agents_are_the_checkouts(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # no agents/ here
    monkeypatch.delenv(AGENTS_ENV, raising=False)
    assert resolve("agents/memory.yaml").samefile(REPO / "agents/memory.yaml")
    assert resolve("agents/memory/setting_I").samefile(REPO / "agents/memory/setting_I")


def test_working_folder_then_variable_then_package(monkeypatch, tmp_path):
    shipped, elsewhere, work = tmp_path / "pkg", tmp_path / "elsewhere", tmp_path / "work"
    monkeypatch.setattr(agent_files, "SHIPPED", shipped)
    monkeypatch.chdir(work.mkdir() or work)
    for folder in (shipped, elsewhere, work / "agents"):
        (folder / "memory").mkdir(parents=True)
    monkeypatch.setenv(AGENTS_ENV, str(elsewhere))
    assert resolve("agents/memory") == Path("agents/memory")  # trained here: it wins
    (work / "agents/memory").rmdir()
    assert resolve("agents/memory") == elsewhere / "memory"
    monkeypatch.delenv(AGENTS_ENV)
    assert resolve("agents/memory") == shipped / "memory"
    (shipped / "memory").rmdir()
    assert resolve("agents/memory") == Path("agents/memory")  # nowhere: where training writes


def test_only_agents_paths_are_searched(monkeypatch, tmp_path):
    monkeypatch.setenv(AGENTS_ENV, str(tmp_path))
    assert candidates("mine/team.yaml") == [Path("mine/team.yaml")]
    assert candidates("/abs/agents/x.yaml") == [Path("/abs/agents/x.yaml")]
    assert candidates("agents/x.yaml")[1:] == [tmp_path / "x.yaml", SHIPPED / "x.yaml"]


def test_missing_weights_say_where_they_were_looked_for(tmp_path):
    config = tmp_path / "mine.yaml"
    text = (REPO / "agents/memory.yaml").read_text()
    text = text.replace("out: agents/memory", "out: agents/mine")
    config.write_text(text.replace("name: memory", "name: mine"))
    r = subprocess.run([sys.executable, "-m", "maniskill_tidy.cli", "eval", "--policy", str(config),
                        "--episodes", "1", "--out", str(tmp_path / "run")],
                       cwd=tmp_path, capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert "agents/mine/setting_I/model.pt not found" in line
    assert AGENTS_ENV in line and "train" in line
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("name", ["memory.yaml", "hangrcom/setting_I/model.pt"])
def test_the_package_link_points_at_the_shipped_agents(name):
    assert (SHIPPED / name).is_file()
