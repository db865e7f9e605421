"""HeteroTidy-v1 and -v2: the v2 asset set, and that the look changes while the task does not."""

from __future__ import annotations

import hashlib
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from maniskill_tidy import assets
from maniskill_tidy.assets.derive import (
    ALLOWED_LICENCES,
    FURNITURE_TRIANGLES,
    OBJECT_TRIANGLES,
    Derivation,
)
from maniskill_tidy.houses.furniture import TEMPLATES
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.sim.realistic import DRESSING

DATA = Path(__file__).parent / "data"


def test_manifest_lists_only_shippable_licences_and_every_file_with_its_hash():
    manifest = assets.manifest()
    assert len(manifest) > 100
    for rel, entry in manifest.items():
        data = assets.path(rel).read_bytes()
        assert hashlib.sha256(data).hexdigest() == entry["sha256"], rel
        assert entry["sources"], rel
        for src in entry["sources"]:
            assert src["licence"] in ALLOWED_LICENCES, (rel, src)
    shipped = {
        str(p.relative_to(assets.ASSET_DIR))
        for p in assets.ASSET_DIR.rglob("*")
        if p.is_file() and p.name not in ("manifest.json", "ATTRIBUTION.md")
    }
    assert shipped == set(manifest), "files on disk and in the manifest differ"
    size = sum(assets.path(rel).stat().st_size for rel in manifest)
    assert size < 40e6


def test_every_furniture_and_pickupable_type_has_a_v2_look():
    for t in TEMPLATES:
        assert (
            assets.variants("furniture", t)
            or t in DRESSING
            or TEMPLATES[t].parts(*[lo for lo, _ in TEMPLATES[t].size])[1]
        ), f"{t}: neither a model nor a dressing"
    catalog = load_catalog()
    missing = [t for t in catalog.pickupable if not assets.variants("object", t)]
    assert not missing, missing
    from maniskill_tidy.envs.robots import HIGH_SCOUT, LOW_MANIPULATOR, LOW_SCOUT, MANIPULATOR

    for kind in (LOW_SCOUT, HIGH_SCOUT, MANIPULATOR, LOW_MANIPULATOR):
        entry = assets.manifest()[f"robots/{kind.name}.glb"]
        assert entry["kind"] == "robot"
        # drawn at its final size: the body inside the grid's radius, the head at the camera
        assert max(entry["size"][:2]) / 2 <= kind.radius + 0.005, kind.name
        assert kind.camera_height <= entry["size"][2] <= kind.camera_height + 0.1, kind.name


def test_triangle_budget_holds():
    for rel, entry in assets.manifest().items():
        if entry["kind"] == "furniture":
            assert entry["triangles"] <= FURNITURE_TRIANGLES * 1.1 + 50, rel
        elif entry["kind"] == "object":
            assert entry["triangles"] <= OBJECT_TRIANGLES * 1.1 + 50, rel


def _digest(env, steps: int = 5) -> tuple[str, str]:
    h = hashlib.sha256()
    _, info = env.reset(seed=7)
    rng = np.random.default_rng(1)
    for row in rng.integers(0, 7, (steps, len(env.agent_names))):
        obs, *_ = env.step({n: int(x) for n, x in zip(env.agent_names, row, strict=True)})
        for n in env.agent_names:
            for k in ("rgb", "depth", "segmentation", "pose"):
                h.update(np.ascontiguousarray(obs[n][k]).tobytes())
    h.update(env.render().tobytes())
    return info["episode"], h.hexdigest()


def _renderer() -> dict:
    import sapien

    mesa = subprocess.run(
        ["dpkg-query", "-W", "-f=${Version}", "mesa-vulkan-drivers"],
        capture_output=True,
        text=True,
    ).stdout
    return {"sapien": sapien.__version__, "mesa": mesa}


def test_v1_pixels_are_those_of_the_code_before_v2():
    """The digest of v1's observations and third-person view over 5 steps, recorded with the
    code before v2 existed (commit d824d02), on this renderer."""
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv

    golden = json.loads((DATA / "v1_pixels.json").read_text())
    if _renderer() != golden["renderer"]:
        pytest.skip(f"recorded on {golden['renderer']}, this is {_renderer()}")
    env = HeteroTidyEnv(setting="I", split="test", render_mode="rgb_array")
    try:
        assert _digest(env) == (golden["episode"], golden["sha256"])
    finally:
        env.close()


def test_v2_keeps_the_task_and_the_segmentation_ids_and_is_deterministic():
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv

    v1 = HeteroTidyEnv(setting="I", split="test", obs_mode="none")
    v2 = HeteroTidyEnv(setting="I", split="test", visuals="realistic", render_mode="rgb_array")
    try:
        _, i1 = v1.reset(seed=3)
        o2, i2 = v2.reset(seed=3)
        assert i1["episode"] == i2["episode"]
        extra = {k: v for k, v in v2.instances.items() if k not in v1.instances}
        assert v1.instances.items() <= v2.instances.items()
        assert {i.kind for i in extra.values()} == {"ceiling"}
        assert len(extra) == len(v2.house.rooms)
        for oid in v1.hs.objects:  # the same settled poses: collision shapes are v1's
            assert np.allclose(v1.hs.object_bottom(oid), v2.hs.object_bottom(oid), atol=1e-6)
        seg_ids = set(np.unique(np.concatenate([o2[n]["segmentation"].ravel() for n in o2])))
        assert seg_ids - {0} <= set(v2.instances)
        first = _digest(v2)
        assert _digest(v2) == first
    finally:
        v1.close()
        v2.close()


def test_v2_is_registered_and_agents_looking_up_see_a_ceiling():
    import gymnasium as gym

    from maniskill_tidy.envs.actions import Action

    seen = {}
    for env_id in ("HeteroTidy-v1", "HeteroTidy-v2"):
        env = gym.make(env_id, setting="I", split="test", render_mode="rgb_array")
        try:
            obs, _ = env.reset(seed=0)
            obs, *_ = env.step({n: int(Action.LookUp) for n in obs})
            inner = env.unwrapped
            ids = np.unique(np.concatenate([obs[n]["segmentation"].ravel() for n in obs]))
            seen[env_id] = {inner.instances[i].kind for i in ids if i in inner.instances}
            inner.render()
            for entity in inner.hs.ceilings:  # hidden for the third-person view only
                body = entity.find_component_by_type(sapien_render().RenderBodyComponent)
                assert body.visibility == 1.0
        finally:
            env.close()
    assert "ceiling" in seen["HeteroTidy-v2"] and "ceiling" not in seen["HeteroTidy-v1"]


def sapien_render():
    import sapien

    return sapien.render


@pytest.mark.slow
def test_derivation_reproduces_the_shipped_set(tmp_path):
    """`make assets` from the sources gives the shipped bytes, every file, the manifest and
    ATTRIBUTION.md (needs `make assets`' sources: the sweethome3d-furniture package and the
    robosuite wheel; about 15 s)."""
    sh3d = Path("/usr/share/sweethome3d/furniture")
    wheel = Path(__file__).parents[1] / "out/sources/robosuite-1.5.2-py3-none-any.whl"
    if not (sh3d / "BlendSwap-CC-0.sh3f").exists() or not wheel.exists():
        pytest.skip("derivation sources missing: run `make assets` first")
    out = tmp_path / "data"
    manifest = Derivation(sh3d, wheel, out=out).run()
    assert manifest == assets.manifest()
    for rel in manifest:
        assert hashlib.sha256((out / rel).read_bytes()).hexdigest() == manifest[rel]["sha256"]
    for name in ("manifest.json", "ATTRIBUTION.md"):
        assert (out / name).read_bytes() == (assets.ASSET_DIR / name).read_bytes(), name


def test_a_camera_sees_its_room_and_through_doorways_only():
    from maniskill_tidy.houses.schema import Door, House, Room, Wall
    from maniskill_tidy.sim.visibility import Arc, FloorPlan, camera_arc

    # three rooms in a row, A | B | C, 3 m each, doorways at y = 1.5 (A|B) and y = 0.5 (B|C)
    rooms = [
        Room(r, "LivingRoom", [[x, 0], [x + 3, 0], [x + 3, 3], [x, 3]])
        for r, x in (("A", 0), ("B", 3), ("C", 6))
    ]
    walls = [Wall("w_ab", [3, 0], [3, 3], ["A", "B"]), Wall("w_bc", [6, 0], [6, 3], ["B", "C"])]
    doors = [
        Door("d_ab", "w_ab", ["A", "B"], [3, 1.5], width=0.9),
        Door("d_bc", "w_bc", ["B", "C"], [6, 0.5], width=0.9),
    ]
    house = House.__new__(House)
    house.rooms, house.walls, house.doors = rooms, walls, doors
    plan = FloorPlan(house)
    ahead = camera_arc(0.0, 0.0, np.radians(90))  # looking along +x, level
    assert plan.visible_rooms([1.0, 1.5], ahead) == {"A", "B", "C"}  # through both doorways
    assert plan.visible_rooms([1.0, 0.3], camera_arc(np.pi / 2, 0.0, np.radians(60))) == {"A"}
    back = camera_arc(np.pi, 0.0, np.radians(90))
    assert plan.visible_rooms([1.0, 1.5], back) == {"A"}  # the doorways are behind it
    # from a corner of A every ray through the first doorway passes above the second
    assert plan.visible_rooms([0.2, 0.2], camera_arc(0.3, 0.0, np.radians(90))) == {"A", "B"}
    down = camera_arc(0.0, np.radians(60), np.radians(90))
    assert down.half == np.pi  # looking steeply down, the view reaches behind the camera
    assert plan.visible_rooms([3.1, 1.5], Arc(0.0, 0.1)) == {"A", "B", "C"}  # in a doorway
    assert Arc(0.0, 0.5).meet(Arc(np.pi, 0.5)) is None


@pytest.mark.parametrize("setting", ["I", "II"])
def test_hiding_unseen_rooms_changes_no_pixel(setting):
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv

    kw = {"setting": setting, "split": "test", "visuals": "realistic"}
    hiding = HeteroTidyEnv(**kw)
    drawing = HeteroTidyEnv(**kw, hide_unseen_rooms=False)
    assert hiding.hide_unseen_rooms and not drawing.hide_unseen_rooms
    rng = np.random.default_rng(5)
    hidden = 0
    try:
        for seed in (0, 1):
            hiding.reset(seed=seed)
            drawing.reset(seed=seed)
            for _ in range(12):
                act = {
                    n: int(rng.choice(7, p=[0.5, 0.1, 0.1, 0.1, 0.1, 0.05, 0.05]))
                    for n in hiding.agent_names
                }
                a, *_ = hiding.step(act)
                b, *_ = drawing.step(act)
                for n in hiding.agent_names:
                    hidden += len(hiding.house.rooms) - len(hiding.visible_rooms(n))
                    for key in ("rgb", "depth", "segmentation"):
                        assert np.array_equal(a[n][key], b[n][key]), (seed, n, key)
    finally:
        hiding.close()
        drawing.close()
    assert hidden > 0  # the comparison was not vacuous: rooms were hidden


def test_eval_on_v2_is_its_own_row_and_old_v1_runs_still_resume(tmp_path):
    from maniskill_tidy.eval.leaderboard import collect, row_order
    from maniskill_tidy.eval.runner import RunConfig, evaluate, run_dir

    v1 = RunConfig("expert", "I", "test", None, episodes=1)
    v2 = RunConfig("expert", "I", "test", None, episodes=1, env="HeteroTidy-v2")
    s1 = evaluate(v1, tmp_path, progress=False)
    s2 = evaluate(v2, tmp_path, progress=False)
    assert run_dir(tmp_path, v2).name == "expert-v2" and run_dir(tmp_path, v1).name == "expert"
    assert (s1["policy"], s1["env"]) == ("expert", "HeteroTidy-v1")
    assert (s2["policy"], s2["env"]) == ("expert-v2", "HeteroTidy-v2")
    run = json.loads((run_dir(tmp_path, v2) / "run.json").read_text())
    assert run["env"] == "HeteroTidy-v2"
    # the same episode, the same task: the privileged expert plays it alike in both looks
    r1 = (run_dir(tmp_path, v1) / "episodes.jsonl").read_text().splitlines()
    r2 = (run_dir(tmp_path, v2) / "episodes.jsonl").read_text().splitlines()
    assert json.loads(r1[0])["episode"] == json.loads(r2[0])["episode"]
    # a run file written before "env" existed is a v1 run: it resumes, it is not refused
    path = run_dir(tmp_path, v1) / "run.json"
    old = json.loads(path.read_text())
    del old["env"]
    path.write_text(json.dumps(old))
    assert evaluate(v1, tmp_path, progress=False)["episodes"] == 1
    runs = collect(tmp_path / "eval")["I"]
    assert set(runs) == {"expert", "expert-v2"}
    assert sorted(["expert-v2", "heuristic-none", "expert", "random"], key=row_order) == [
        "random",
        "heuristic-none",
        "expert",
        "expert-v2",
    ]


def test_commands_default_to_v2_and_a_team_reading_v1_pixels_through_weights_to_v1(capsys):
    import argparse

    import maniskill_tidy
    from maniskill_tidy.cli.evaluation import _look
    from maniskill_tidy.cli.options import env_option
    from maniskill_tidy.policies import team_class
    from maniskill_tidy.policies.agent_config import perception_look

    p = argparse.ArgumentParser()
    env_option(p)
    assert p.parse_args([]).env == maniskill_tidy.DEFAULT_ENV == "HeteroTidy-v2"
    # scripted teams (and the memory team, which reads only segmentation) play any look: v2
    assert _look("heuristic-none", None) == "HeteroTidy-v2"
    assert _look("memory", None) == "HeteroTidy-v2" and capsys.readouterr().out == ""
    # the paper's model and QMIX read RGB through agents/perception, trained on v1's views
    assert perception_look("agents/perception/knowledge") == "HeteroTidy-v1"
    assert perception_look("agents/perception-v2/knowledge") == "HeteroTidy-v2"
    assert team_class("agents/wo_comm.yaml").look == "HeteroTidy-v1"
    assert _look("hangrcom", None) == "HeteroTidy-v1"
    assert "trained on HeteroTidy-v1's views; playing HeteroTidy-v1" in capsys.readouterr().out
    assert _look("agents/qmix.yaml", None) == "HeteroTidy-v1"
    capsys.readouterr()
    assert _look("hangrcom", "HeteroTidy-v2") == "HeteroTidy-v2"  # told: played, and said so
    assert "measures the look change" in capsys.readouterr().out
    assert _look("expert", "HeteroTidy-v1") == "HeteroTidy-v1" and capsys.readouterr().out == ""


def test_a_learned_teams_look_is_read_from_its_perception_card_when_asked(tmp_path):
    """Not when its class is made: a perception retrained in the other look moves the team's
    default look without a restart, and importing the teams reads no card."""
    from maniskill_tidy.policies.agent_config import PerceptionLook

    class Team:
        look = PerceptionLook(tmp_path)

    from maniskill_tidy.policies.learned import learned_team_class

    config = tmp_path / "team.yaml"  # a team made from a config (eval --policy CONFIG.yaml)
    config.write_text(
        f"base: {Path('agents/hangrcom.yaml').resolve()}\nname: look-test\nperception: {tmp_path}\n"
    )
    made = learned_team_class(config)
    assert Team.look == made.look == "HeteroTidy-v1"  # no card yet: perceptions before looks
    (tmp_path / "card.json").write_text(json.dumps({"config": {"env": "HeteroTidy-v2"}}))
    assert Team.look == Team().look == made.look == "HeteroTidy-v2"


def test_what_rests_on_a_model_stays_above_it():
    """Over the middle of each surface of a static piece, the shipped model lies under the
    height the spec puts objects at: a thin object on a cushion or in a tub stays in view."""
    import open3d as o3d
    import trimesh

    from maniskill_tidy.assets.derive import SURFACE_SPAN, nominal_size
    from maniskill_tidy.houses.furniture import parts_for

    checked = 0
    for rel, entry in assets.manifest().items():
        if entry["kind"] != "furniture" or not entry.get("surface_fit"):
            continue
        mesh = trimesh.load(assets.path(rel), force="mesh")
        caster = o3d.t.geometry.RaycastingScene()
        caster.add_triangles(
            o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
            o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)),
        )
        surfaces, _ = parts_for(entry["type"], nominal_size(entry["type"]))
        for s in surfaces:
            if s.name not in entry["surface_fit"]:
                continue
            (cx, cy, z), (sw, sd) = s.center, s.size
            gx, gy = np.meshgrid(
                np.linspace(cx - SURFACE_SPAN * sw, cx + SURFACE_SPAN * sw, 9),
                np.linspace(cy - SURFACE_SPAN * sd, cy + SURFACE_SPAN * sd, 9),
            )
            rays = np.zeros((gx.size, 6), np.float32)
            rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = gx.ravel(), gy.ravel(), 5.0, -1.0
            t = caster.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
            assert np.percentile(5.0 - t[np.isfinite(t)], 90) <= z, (rel, s.name)
            # and over the whole surface, arms, backs and walls cover little of it
            gx, gy = np.meshgrid(
                np.linspace(cx - sw / 2 + 0.03, cx + sw / 2 - 0.03, 20),
                np.linspace(cy - sd / 2 + 0.03, cy + sd / 2 - 0.03, 20),
            )
            rays = np.zeros((gx.size, 6), np.float32)
            rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = gx.ravel(), gy.ravel(), 5.0, -1.0
            t = caster.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
            covered = np.mean(5.0 - t[np.isfinite(t)] > z + 0.03)
            assert covered <= 0.1, (rel, s.name, covered)
            checked += 1
    assert checked >= 15


def test_derive_assets_names_a_missing_source_before_writing_anything(tmp_path):
    from maniskill_tidy.cli import main

    out = tmp_path / "data"
    assert main(["derive-assets", "--sh3d", str(tmp_path), "--out", str(out)]) == 2
    assert main(["derive-assets", "--robosuite", str(tmp_path / "no.whl"), "--out", str(out)]) == 2
    assert not out.exists() and not list(tmp_path.glob(".data*"))
