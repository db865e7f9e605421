"""Every furniture and pickupable type as HeteroTidy-v2 draws it, with source and licence.

``maniskill-tidy show-assets --out docs`` writes ``assets-furniture.png``, ``assets-objects.png``
and ``assets.md`` (per type: how it is drawn, each variant's source model, licence, author and
triangles). Pieces with doors and drawers are drawn closed from their dressed procedural parts.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import sapien
from tqdm import tqdm

from maniskill_tidy import assets
from maniskill_tidy.houses.furniture import TEMPLATES, parts_for
from maniskill_tidy.houses.schema import Furniture, House
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.sim import environment_map
from maniskill_tidy.sim.furniture_shapes import Part, body_parts, link_parts
from maniskill_tidy.sim.house_scene import add_part
from maniskill_tidy.sim.realistic import DRESSING, WHY_PROCEDURAL, RealisticLook, model_scale

TILE = 200  # px


def nominal_piece(type_name: str) -> Furniture:
    size = [round((lo + hi) / 2, 3) for lo, hi in TEMPLATES[type_name].size]
    surfaces, joints = parts_for(type_name, size)
    return Furniture(f"{type_name}_0", type_name, "r", [0.0, 0.0, 0.0], 0.0, size, surfaces, joints)


class Studio:
    """A lit scene and a camera that frames one thing at a time, from its front-right."""

    def __init__(self) -> None:
        self.scene = sapien.Scene()
        self.scene.render_system.cubemap = environment_map.cubemap()
        self.scene.set_ambient_light([0.2, 0.2, 0.2])
        self.scene.add_directional_light([-0.4, -0.8, -1.0], [0.9, 0.9, 0.88])
        self.camera = self.scene.add_camera("studio", TILE, TILE, math.radians(35), 0.01, 50)

    def shoot(self, build, view=(0.55, 1.4, 0.75)) -> np.ndarray:
        builder = self.scene.create_actor_builder()
        build(builder)
        actor = builder.build_static("subject")
        body = actor.find_component_by_type(sapien.render.RenderBodyComponent)
        lo, hi = body.compute_global_aabb_tight()
        centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
        eye = centre + np.asarray(view) / 1.7 * radius / math.tan(math.radians(17))
        forward = (centre - eye) / np.linalg.norm(centre - eye)
        left = np.cross([0.0, 0.0, 1.0], forward)
        left /= np.linalg.norm(left)
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = (
            forward,
            left,
            np.cross(forward, left),
            eye,
        )
        self.camera.entity.set_pose(sapien.Pose(pose))
        self.scene.update_render()
        self.camera.take_picture()
        rgba = self.camera.get_picture("Color")
        self.scene.remove_entity(actor)
        return (rgba[..., :3].clip(0, 1) * 255).astype(np.uint8)


def _look() -> RealisticLook:
    house = House.__new__(House)
    house.id, house.seed, house.rooms, house.lights = "gallery", 0, [], []
    return RealisticLook(house)


def furniture_tiles(studio: Studio) -> list[tuple[str, str, np.ndarray]]:
    look, out = _look(), []
    for t in tqdm(sorted(TEMPLATES), desc="furniture"):
        f = nominal_piece(t)
        if look.furniture_model(f) is None:  # dressed procedural parts, drawn closed
            parts = body_parts(f) + [p for j in f.joints for p in link_parts(f, j)]

            def build(b, f=f, parts=parts):
                for p in parts:
                    add_part(b, Part(p.kind, p.center, p.half, p.colour), collision=False,
                             mat=look.part_material(f, p.colour))  # fmt: skip

            out.append((t, "procedural parts, dressed", studio.shoot(build)))
            continue
        for rel in assets.variants("furniture", t):

            def build(b, rel=rel, f=f):
                b.add_visual_from_file(str(assets.path(rel)), scale=model_scale(rel, f))

            out.append((t, _credit(rel), studio.shoot(build)))
    return out


def object_tiles(studio: Studio) -> list[tuple[str, str, np.ndarray]]:
    out = []
    for t in tqdm(sorted(load_catalog().pickupable), desc="objects"):
        for rel in assets.variants("object", t):

            def build(b, rel=rel):
                b.add_visual_from_file(str(assets.path(rel)))

            out.append((t, _credit(rel), studio.shoot(build)))
    return out


ROBOT_VIEWS = ((0.55, 1.4, 0.75), (-1.2, -0.9, 0.6))  # front-left, back-right: the arm


def robot_tiles(studio: Studio) -> list[tuple[str, str, np.ndarray]]:
    """The four robot kinds, each from the front and from behind."""
    out = []
    for rel in sorted(r for r in assets.manifest() if r.startswith("robots/")):
        for view in ROBOT_VIEWS:

            def build(b, rel=rel):
                b.add_visual_from_file(str(assets.path(rel)))

            out.append((Path(rel).stem, _credit(rel), studio.shoot(build, view)))
    return out


def _credit(rel: str) -> str:
    src = assets.manifest()[rel]["sources"]
    model = Path(rel).stem
    return f"{model} ({', '.join(sorted({s['licence'] for s in src}))})"


def sheet(tiles: list[tuple[str, str, np.ndarray]], title: str, out: Path, cols: int = 8) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = math.ceil(len(tiles) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(cols * 2.0, rows * 2.3))
    for ax in np.ravel(axes):
        ax.axis("off")
    for ax, (type_name, credit, image) in zip(np.ravel(axes), tiles, strict=False):
        ax.imshow(image)
        ax.set_title(f"{type_name}\n{credit}", fontsize=6.5)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    tmp = out.with_name(f".{out.name}.tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(out)
    return out


def table() -> str:
    """Markdown: per type, how v2 draws it and every variant's source."""
    look = _look()
    lines = [
        "| type | drawn as | variant: source model, licence, author | triangles |",
        "|---|---|---|---|",
    ]
    pickupable = sorted(load_catalog().pickupable)
    for kind, types in (("furniture", sorted(TEMPLATES)), ("object", pickupable)):
        for t in types:
            rels = assets.variants(kind, t)
            if kind == "furniture" and look.furniture_model(nominal_piece(t)) is None:
                joints = nominal_piece(t).joints
                why = "doors/drawers follow joints" if joints else WHY_PROCEDURAL[t]
                tex = look.dressing(t)[0]
                tex = "a wood per house" if tex == look.wood and t not in DRESSING else tex
                if t in DRESSING and DRESSING[t][0] != tex:
                    tex = "the house's cabinet wood"
                lines.append(f"| {t} | procedural parts in `{tex}` ({why}) | - | primitives |")
                continue
            cells, tris = [], []
            for rel in rels:
                e = assets.manifest()[rel]
                src = e["sources"][0]
                how = "shape" if src.get("source") in ("maniskill-tidy", "robosuite") else "model"
                author = src.get("author") or src.get("holder", "")
                cells.append(f"`{Path(rel).stem}` ({how}): {src['source']}, {src['licence']}, "
                             f"{author}")  # fmt: skip
                tris.append(str(e["triangles"]))
            drawn = "textured shape" if all("shape" in c for c in cells) else "mesh"
            lines.append(f"| {t} | {drawn} | {'<br>'.join(cells)} | {', '.join(tris)} |")
    return "\n".join(lines)


def write_gallery(out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    studio = Studio()
    furniture = sheet(
        furniture_tiles(studio),
        "HeteroTidy-v2: every furniture type and variant",
        out / "assets-furniture.png",
    )
    objects = sheet(
        object_tiles(studio),
        "HeteroTidy-v2: every pickupable type and variant (at its catalogue size)",
        out / "assets-objects.png",
        cols=10,
    )
    robots = sheet(
        robot_tiles(studio),
        "HeteroTidy-v2: the robot kinds, modelled by the project (front, back)",
        out / "assets-robots.png",
        cols=4,
    )
    page = out / "assets.md"
    page.write_text(
        "# The v2 assets\n\n"
        "Written by `maniskill-tidy show-assets --out docs`. Sources, licences and authors come "
        "from `maniskill_tidy/assets/data/manifest.json`, which holds what `derive-assets` read "
        "from each source's own licence files; the credits in full (title, author, origin, "
        "licence URI, what was modified) are in `maniskill_tidy/assets/data/ATTRIBUTION.md`. "
        "The robots are modelled by the project (`maniskill_tidy/assets/robots.py`), and so is "
        "the environment map (`assets/lighting.py`); shapes are built by "
        "`maniskill_tidy/assets/shapes.py` around a robosuite (MIT) texture.\n\n"
        "![robots](assets-robots.png)\n\n"
        "![furniture](assets-furniture.png)\n\n![objects](assets-objects.png)\n\n" + table() + "\n"
    )
    return [robots, furniture, objects, page]
