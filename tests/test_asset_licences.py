"""What ships in v2's asset set may ship: licences read from the sources' own files, refused
when they are not shippable, credited in ATTRIBUTION.md; robots and lighting of our own."""

from __future__ import annotations

import hashlib
import re
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest

from maniskill_tidy import assets
from maniskill_tidy.assets.derive import OWN, Derivation
from maniskill_tidy.assets.licences import URIS, audit, check, identify
from maniskill_tidy.assets.sources import Sh3fArchive

ROOT = Path(__file__).parents[1]


def known_sources() -> set[str]:
    return set(tomllib.loads(assets.SELECTION.read_text())["sources"]) | {"maniskill-tidy"}


def test_the_shipped_manifest_passes_the_licence_audit():
    assert audit(assets.manifest(), known_sources()) == []
    for rel, entry in assets.manifest().items():
        assert hashlib.sha256(assets.path(rel).read_bytes()).hexdigest() == entry["sha256"]


def without(d: dict, key: str) -> dict:
    return {k: v for k, v in d.items() if k != key}


def test_the_audit_refuses_fetch_meshes_unstated_origins_nc_and_uncredited_cc_by():
    fine = {
        "source": "Scopia",
        "model": "scopia/cup/cup.obj",
        "licence": "CC-BY-3.0",
        "licence_file": "Scopia.sh3f:LICENSE.TXT",
        "title": "Cup",
        "author": "Scopia",
        "url": "http://www.sweethome3d.com/",
    }
    fetch = {  # what the manifest said before: the wheel's code licence, not the meshes'
        "source": "mani-skill",
        "model": "mani_skill/assets/robots/fetch/fetch_description/meshes",
        "licence": "Apache-2.0",
    }
    manifest = {
        "objects/Cup/cup.glb": {"sources": [fine]},
        "robots/manipulator.glb": {"sources": [fetch]},
        "environment.hdr": {"sources": [fine | {"model": "mani_skill/x/default.hdr"}]},
        "objects/Pen/pen.glb": {"sources": [fine | {"licence": "CC-BY-NC-SA-4.0"}]},
        "objects/Mug/mug.glb": {"sources": [without(fine, "url")]},
        "objects/Egg/egg.glb": {"sources": [without(fine, "licence_file")]},
        "objects/Box/box.glb": {"sources": []},
    }
    problems = audit(manifest, known_sources())
    flagged = {p.split(" ")[0].rstrip(":") for p in problems}
    assert flagged == set(manifest) - {"objects/Cup/cup.glb"}
    assert any("robots/manipulator.glb" in p and "unshippable origin" in p for p in problems)
    assert any("robots/manipulator.glb" in p and "unknown source" in p for p in problems)
    assert any("CC-BY-NC-SA-4.0 may not ship" in p for p in problems)
    assert any("objects/Mug/mug.glb" in p and "without its url" in p for p in problems)


@pytest.mark.parametrize(
    "text, spdx",
    [
        ("Released under\nCreative Commons Attribution 3.0\n", "CC-BY-3.0"),
        ("Released under\nCreative Commons Zero (Public Domain)\n", "CC0-1.0"),
        ('<h3>Released under <a href="https://creativecommons.org/licenses/by/3.0/">'
         "Creative Commons Attribution 3.0</a></h3>", "CC-BY-3.0"),  # fmt: skip
        # words beat a badge's link: Blend Swap's older pages link the public domain mark
        ('<a href="http://creativecommons.org/publicdomain/mark/1.0/"><img></a> released under '
         "the following license: Creative Commons Zero (Public Domain)", "CC0-1.0"),  # fmt: skip
        ("http://creativecommons.org/licenses/by/3.0/us/", "CC-BY-3.0-US"),
        ("Creative Commons Attribution-NonCommercial-ShareAlike 4.0", "CC-BY-NC-SA-4.0"),
        ('<license>CC-BY-NC-SA-4.0</license> creativecommons.org/licenses/by-nc-sa/4.0/',
         "CC-BY-NC-SA-4.0"),  # fmt: skip
        ("MIT License\n\nPermission is hereby granted, free of charge, to any person", "MIT"),
        ("Apache License\n                Version 2.0, January 2004", "Apache-2.0"),
        ("All rights reserved.", None),
    ],
)
def test_a_licence_is_read_from_the_words_of_its_file(text, spdx):
    assert identify(text) == spdx


def test_check_refuses_what_may_not_ship_and_names_the_file():
    assert check("CC0-1.0", "m", "f") == "CC0-1.0"
    with pytest.raises(ValueError, match="CC-BY-NC-SA-4.0.*may not ship"):
        check("CC-BY-NC-SA-4.0", "robot", "package.xml")
    with pytest.raises(ValueError, match="x.sh3f:LICENSE.TXT states no licence"):
        check(None, "model", "x.sh3f:LICENSE.TXT")


def _archive(tmp_path: Path, licence: str, model_licence: str | None) -> Sh3fArchive:
    """A furniture archive as Sweet Home 3D lays one out, with one model."""
    path = tmp_path / "Test.sh3f"
    catalog = (
        "id=Test\nname=Test\nlicense=whatever\nprovider=www.example.org\n\n"
        "id#1=Test#thing\nname#1=Thing\nmodel#1=/test/thing/thing.obj\n"
        "width#1=10\ndepth#1=10\nheight#1=10\ncreator#1=Catalog Person\n"
    )
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("PluginFurnitureCatalog.properties", catalog)
        z.writestr("LICENSE.TXT", licence)
        z.writestr("test/thing/thing.obj", "v 0 0 0\n")
        if model_licence is not None:
            z.writestr("test/thing/BLENDSWAP_LICENSE.txt", model_licence)
    return Sh3fArchive(path, "Test")


BLEND = (
    'Thank you for downloading "A Thing" by Someone\nReleased under\n{licence}\n'
    "Downloaded from http://www.blendswap.com/blends/view/123\n"
)


def test_a_models_title_author_origin_and_licence_come_from_its_own_files(tmp_path):
    arc = _archive(tmp_path, "http://creativecommons.org/licenses/by/3.0/",
                   BLEND.format(licence="Creative Commons Attribution 3.0"))  # fmt: skip
    credit = arc.credit(arc.model("thing"))
    assert (credit["title"], credit["author"], credit["licence"]) == (
        "A Thing",
        "Someone",
        "CC-BY-3.0",
    )
    assert credit["url"] == "http://www.blendswap.com/blends/view/123"
    assert credit["licence_file"] == "Test.sh3f:test/thing/BLENDSWAP_LICENSE.txt"

    (tmp_path / "b").mkdir()
    bare = _archive(tmp_path / "b", "http://creativecommons.org/licenses/by/3.0/us/", None)
    credit = bare.credit(bare.model("thing"))  # no file of its own: the archive and catalog
    assert (credit["title"], credit["author"], credit["licence"]) == (
        "Thing",
        "Catalog Person",
        "CC-BY-3.0-US",
    )
    assert credit["url"] == "http://www.example.org/"
    assert credit["licence_file"] == "Test.sh3f:LICENSE.TXT"


@pytest.mark.parametrize(
    "licence, model_licence, error",
    [
        ("http://creativecommons.org/licenses/by/3.0/",
         BLEND.format(licence="Creative Commons Attribution-NonCommercial 3.0"),
         "CC-BY-NC-3.0"),  # fmt: skip
        ("Use as you like.", None, "states no licence"),
        ("http://creativecommons.org/licenses/by-sa/3.0/", None, "CC-BY-SA-3.0"),
    ],
)
def test_a_model_that_may_not_ship_is_refused(tmp_path, licence, model_licence, error):
    arc = _archive(tmp_path, licence, model_licence)
    with pytest.raises(ValueError, match=error):
        arc.credit(arc.model("thing"))


def _attribution_items() -> dict[str, str]:
    """ATTRIBUTION.md's items by their source path."""
    text = (assets.ASSET_DIR / "ATTRIBUTION.md").read_text()
    items = {}
    for block in re.split(r"\n(?=- \*\*)", text):
        if m := re.search(r"  - source: `([^`]+)`", block):
            items[m.group(1)] = block
    return items


def test_attribution_credits_every_cc_by_work_with_title_author_url_and_licence_uri():
    items = _attribution_items()
    checked = 0
    for rel, entry in assets.manifest().items():
        for src in entry["sources"]:
            block = items[src["model"]]  # every work has its item
            assert f"`{src['licence_file']}`" in block and URIS[src["licence"]] in block, rel
            assert rel in block  # where it is used
            if src["licence"].startswith("CC-BY"):
                assert f'"{src["title"]}"' in block and f"by {src['author']}" in block, rel
                assert f"<{src['url']}>" in block, rel
                assert "modified: decimated" in block or "modified: downscaled" in block, rel
                checked += 1
    assert checked >= 40
    salt = items["blendswap-cc-by/saltShaker/saltShaker.obj"]
    assert '"Salt and Pepper Shaker"' in salt and "blends/view/92173" in salt
    assert "Permission is hereby granted" in (assets.ASSET_DIR / "ATTRIBUTION.md").read_text()


def test_robots_and_lighting_are_our_own_and_derive_to_the_shipped_bytes(tmp_path):
    """The files the project models need no source: derived here, they are the shipped ones
    (the rest needs `make assets`' sources: tests/test_looks.py, slow)."""
    own = {rel for rel in assets.manifest() if rel.startswith(OWN)}
    assert len(own) == 5
    none = tmp_path / "no-such-source"
    manifest = Derivation(none, none / "x.whl", out=tmp_path / "data", only=own).run()
    for rel in own:
        assert manifest[rel]["sha256"] == assets.manifest()[rel]["sha256"], rel
        assert manifest[rel]["sources"][0]["source"] == "maniskill-tidy"
        assert manifest[rel]["sources"][0]["licence"] == identify((ROOT / "LICENSE").read_text())


def test_the_robot_looks_match_the_env_kinds_and_keep_the_arm_behind_the_camera():
    from maniskill_tidy.assets import robots
    from maniskill_tidy.envs.robots import HIGH_SCOUT, LOW_MANIPULATOR, LOW_SCOUT, MANIPULATOR

    for kind in (LOW_SCOUT, HIGH_SCOUT, MANIPULATOR, LOW_MANIPULATOR):
        look = robots.KINDS[kind.name]
        assert (look.camera_height, look.manipulator, look.colour) == (
            kind.camera_height,
            kind.manipulator,
            kind.colour,
        )
        assert look.hold_height == kind.hold_offset[1]
        assert robots.RADIUS == pytest.approx(kind.radius)
        parts = robots.robot_parts(kind.name)
        assert robots.triangles(parts) <= robots.TRIANGLES[kind.name]
        verts = np.concatenate([m.vertices for m, _ in parts])
        assert np.linalg.norm(verts[:, :2], axis=1).max() <= kind.radius + 1e-6
        # the painted shell of a manipulator's arm (off the centre line) stays behind ARM_FRONT
        paint = [m for m, look_ in parts if tuple(look_["colour"]) == kind.colour]
        painted = np.concatenate([m.vertices for m in paint])
        _, base_top = robots.base(look)
        arm = painted[(np.abs(painted[:, 1]) > 0.08) & (painted[:, 2] > base_top + 1e-6)]
        assert bool(len(arm)) == kind.manipulator
        assert not len(arm) or arm[:, 0].max() <= robots.ARM_FRONT + 1e-6


def test_the_environment_map_is_a_room_of_our_own():
    from maniskill_tidy.assets.lighting import room_map

    image = room_map(256, 128)
    assert image.shape == (128, 256, 3) and 0.0 <= image.min() and image.max() <= 1.0
    assert image[0].mean() > 0.9  # the lamp at the zenith
    assert image[-1].mean() < 0.4  # the floor under the robot
    assert (image[40:60].max(axis=2) > 0.99).mean() > 0.1  # windows around the horizon


def test_the_package_licence_covers_what_ships():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    spdx = {src["licence"] for e in assets.manifest().values() for src in e["sources"]}
    assert set(meta["license"].split(" AND ")) == spdx
    assert {"LICENSE", "maniskill_tidy/assets/data/ATTRIBUTION.md"} <= set(meta["license-files"])
    assert identify((ROOT / "LICENSE").read_text()) == "Apache-2.0"


def test_teammates_see_the_modelled_robots_where_v1_draws_its_robots():
    """Test episode 5 of Setting I: agents 1 and 2 see the manipulator in both looks; v2's
    robots carry the same segmentation ids, cover a like area, and no agent sees its own arm."""
    from maniskill_tidy.envs.actions import Action
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv

    seen = {}
    for visuals in ("flat", "realistic"):
        env = HeteroTidyEnv(setting="I", split="test", visuals=visuals)
        try:
            obs, _ = env.reset(options={"episode": 5})
            ids = {e.per_scene_id: n for n, e in zip(env.agent_names, env.robots, strict=True)}
            frames = [obs]
            for _ in range(2):  # tilt every camera fully down: its own body under it
                frames.append(env.step({n: int(Action.LookDown) for n in env.agent_names})[0])
            for i, frame in enumerate(frames):
                for name in env.agent_names:
                    seg = frame[name]["segmentation"]
                    for rid, robot in ids.items():
                        seen[(visuals, i, name, robot)] = int((seg == rid).sum())
        finally:
            env.close()
    for viewer, other in (("agent_1", "agent_2"), ("agent_2", "agent_1")):
        for i in range(3):
            v1, v2 = seen[("flat", i, viewer, other)], seen[("realistic", i, viewer, other)]
            assert v1 > 600 and 0.6 < v2 / v1 < 1.6, (viewer, i, v1, v2)
    for (visuals, i, name, robot), pixels in seen.items():
        if name == robot and visuals == "realistic":  # its own base, looking down; not its arm
            assert pixels <= seen[("flat", i, name, robot)] + 200, (name, i, pixels)
