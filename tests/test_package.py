"""What a user reads about the package agrees with the package: version, citation, changelog."""

from __future__ import annotations

import tomllib
from pathlib import Path

import yaml

import maniskill_tidy

ROOT = Path(__file__).resolve().parents[1]


def test_version_citation_and_changelog_agree():
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert maniskill_tidy.__version__ == version
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["version"] == version
    assert cff["license"] == "Apache-2.0"
    paper = cff["references"][0]
    assert paper["title"] == "Heterogeneous Embodied Multi-Agent Collaboration"
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert f"## [{version}]" in changelog and "## [Unreleased]" in changelog
    assert "@misc{" in (ROOT / "README.md").read_text()


def test_the_layout_page_names_every_module():
    """docs/layout.md lists each package's modules: a module added is a line to add there."""
    text = (ROOT / "docs" / "layout.md").read_text()
    block = text[text.index("## Modules") :]
    package = ROOT / "maniskill_tidy"
    missing = [str(p.relative_to(package)) for p in package.rglob("*.py")
               if p.name != "__init__.py" and p.name not in block]  # fmt: skip
    assert not missing, f"docs/layout.md does not name {missing}"
