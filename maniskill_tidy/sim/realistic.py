"""The v2 look: what a house wears in ``HeteroTidy-v2`` (the task under it is v1's).

Floors, walls and ceilings are meshes with world-scaled UVs (a texture repeats every
``TILE`` metres) and textures chosen per room from the house's seed; static furniture and
objects are the derived models of ``assets/`` (a variant per piece, from the seed), scaled to
the piece's size so that the level objects rest on is the spec's surface; furniture with doors
and drawers keeps its procedural parts, so they still follow the joints, and wears wood, steel
or enamel. Nothing here changes a collision shape, a pose or a segmentation id: visuals only.
"""

from __future__ import annotations

import math
import tomllib
import zlib
from functools import cache

import numpy as np
import sapien

from maniskill_tidy import assets
from maniskill_tidy.houses.schema import Furniture, House, PlacedObject
from maniskill_tidy.sim import environment_map
from maniskill_tidy.sim.appearance import RGB, furniture_colour

TILE = {"floor": 1.0, "wall": 1.5, "ceiling": 2.0}  # metres per texture repeat
CEILING_GAP = 0.002  # metres below the top of the walls
FRAME = 0.035  # metres, half the width of a door trim

# The procedural pieces (doors and drawers follow their joints): main texture and tint.
DRESSING: dict[str, tuple[str, RGB]] = {
    "CounterTop": ("wood_light", (1.0, 1.0, 1.0)),
    "Sink": ("wood_light", (1.0, 1.0, 1.0)),
    "Fridge": ("steel", (1.05, 1.05, 1.08)),
    "Microwave": ("metal_dark", (0.9, 0.9, 0.95)),
    "Safe": ("metal_dark", (0.8, 0.82, 0.85)),
    "Dresser": ("wood_red", (1.0, 1.0, 1.0)),
    "Desk": ("wood_dark", (1.2, 1.2, 1.2)),
    "SideTable": ("wood_light", (0.9, 0.85, 0.8)),
    "ShelvingUnit": ("wood_grey", (0.95, 0.9, 0.85)),
    "Bathtub": ("ceiling", (1.0, 1.0, 1.02)),  # enamel: no archive tub leaves its basin free
    "TowelHolder": ("steel", (1.0, 1.0, 1.0)),
    "HandTowelHolder": ("steel", (1.0, 1.0, 1.0)),
    "ToiletPaperHanger": ("steel", (1.0, 1.0, 1.0)),
}
# Why a piece without joints keeps procedural parts (with joints: doors and drawers follow them).
WHY_PROCEDURAL = {
    "ShelvingUnit": "objects rest on the spec's three shelves",
    "TowelHolder": "towels hang on the spec's bar",
    "HandTowelHolder": "towels hang on the spec's bar",
    "ToiletPaperHanger": "paper hangs on the spec's bar",
    "Bathtub": "no archive tub leaves the spec's basin free",
}
WOODS = ("wood_light", "wood_dark", "wood_red", "wood_grey")
OWN_WOOD = ("Desk", "Dresser", "ShelvingUnit")  # the rest take the house's cabinet wood
TOPS = {"CounterTop": "stone_top", "Sink": "stone_top"}
METAL_PARTS = {(0.75, 0.77, 0.8): "steel", (0.25, 0.25, 0.27): "steel"}  # basin, handles


@cache
def room_materials() -> dict:
    return tomllib.loads(assets.SELECTION.read_text())["rooms"]


@cache
def texture(name: str) -> sapien.render.RenderTexture2D:
    return sapien.render.RenderTexture2D(str(assets.path(f"textures/{name}.png")))


@cache
def textured(name: str, tint: RGB = (1.0, 1.0, 1.0), roughness: float = 0.8, metallic=0.0):
    mat = sapien.render.RenderMaterial(
        base_color=[*tint, 1.0], roughness=roughness, metallic=metallic
    )
    mat.base_color_texture = texture(name)
    return mat


def pick(seq, *key) -> object:
    """A stable choice from ``seq`` for ``key`` (the house's seed and a name)."""
    return seq[zlib.crc32("/".join(str(k) for k in key).encode()) % len(seq)]


def quad_mesh(corners: np.ndarray, normal, tile: float, material) -> sapien.render.RenderShape:
    """A rectangle (4 corners, counter-clockwise seen from ``normal``) with metric UVs."""
    corners = np.asarray(corners, dtype=np.float32)
    u_axis = corners[1] - corners[0]
    length = float(np.linalg.norm(u_axis))
    u_axis /= max(length, 1e-9)
    v_axis = np.cross(np.asarray(normal, dtype=np.float32), u_axis)
    rel = corners - corners[0]
    uv = np.stack([rel @ u_axis, rel @ v_axis], axis=1) / tile
    normals = np.tile(np.asarray(normal, dtype=np.float32), (4, 1))
    faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    return sapien.render.RenderShapeTriangleMesh(
        corners, faces, normals, uv.astype(np.float32), material
    )


def box_faces(center, half, yaw: float, tile: float, material) -> list:
    """The six faces of a box turned by ``yaw`` about z, each with metric UVs."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    hx, hy, hz = half
    shapes = []
    for axis in range(3):
        for sign in (-1, 1):
            n = np.zeros(3)
            n[axis] = sign
            a, b = (axis + 1) % 3, (axis + 2) % 3  # e_a x e_b = e_axis
            if sign < 0:
                a, b = b, a
            corners = []
            for da, db in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis] = sign
                p[a], p[b] = da, db
                corners.append(rot @ (p * [hx, hy, hz]) + center)
            shapes.append(quad_mesh(np.array(corners), rot @ n, tile, material))
    return shapes


def attach(entity: sapien.Entity, shapes: list) -> None:
    """Give an entity built without visuals its render shapes (its segmentation id stays)."""
    body = sapien.render.RenderBodyComponent()
    for shape in shapes:
        body.attach(shape)
    entity.add_component(body)


def model_scale(rel: str, f: Furniture) -> list[float]:
    """Scale of a derived model (made for the type's nominal size, its surfaces just under the
    spec's: ``derive.surface_safe_height``) for a piece of another size."""
    w, d, h = assets.manifest()[rel]["nominal_size"]
    return [f.size[0] / w, f.size[1] / d, f.size[2] / h]


class RealisticLook:
    """The v2 choices for one house: textures per room, a model per piece."""

    def __init__(self, house: House) -> None:
        self.house = house
        self.seed = house.seed if house.seed is not None else zlib.crc32(house.id.encode())
        rooms = room_materials()
        default = rooms["LivingRoom"]
        self.floor = {}
        self.wall = {}
        for r in house.rooms:
            spec = rooms.get(r.type, default)
            self.floor[r.id] = pick(spec["floor"], self.seed, r.id, "floor")
            self.wall[r.id] = pick(spec["wall"], self.seed, r.id, "wall")
        self.wood = pick(WOODS, self.seed, "cabinets")

    # ------------------------------------------------------------------ rooms
    def floor_shapes(self, room, strips) -> list:
        mat = textured(self.floor[room.id], roughness=0.6)
        return [
            quad_mesh(
                np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]]),
                (0.0, 0.0, 1.0),
                TILE["floor"],
                mat,
            )
            for x0, y0, x1, y1 in strips
        ]

    def ceiling_shapes(self, room, strips, height: float) -> list:
        mat = textured("ceiling", roughness=0.9)
        z = height - CEILING_GAP
        return [
            quad_mesh(
                np.array([[x0, y0, z], [x0, y1, z], [x1, y1, z], [x1, y0, z]]),
                (0.0, 0.0, -1.0),
                TILE["ceiling"],
                mat,
            )
            for x0, y0, x1, y1 in strips
        ]

    def wall_material(self, wall) -> sapien.render.RenderMaterial:
        room = wall.rooms[0] if wall.rooms else None
        return textured(self.wall.get(room, "wall_white"), roughness=0.9)

    def wall_shapes(self, wall, boxes) -> list:
        """Each side of an interior wall wears its own room's paint."""
        shapes = []
        for center, half, yaw in boxes:
            faces = box_faces(center, half, yaw, TILE["wall"], self.wall_material(wall))
            if len(wall.rooms) == 2:
                # faces 2 and 3 are the -y and +y sides (the wall's two rooms)
                for k, room in zip((2, 3), self._sides(wall, center, yaw), strict=True):
                    mat = textured(self.wall.get(room, "wall_white"), roughness=0.9)
                    faces[k] = box_faces(center, half, yaw, TILE["wall"], mat)[k]
            shapes += faces
        return shapes

    def _sides(self, wall, center, yaw) -> tuple[str, str]:
        """Which of the wall's rooms lies on its -y side and which on its +y side."""
        from matplotlib.path import Path as PolygonPath

        ny = np.array([-math.sin(yaw), math.cos(yaw)])
        probe = np.asarray(center[:2]) - 0.3 * ny
        a, b = wall.rooms
        room_a = next(r for r in self.house.rooms if r.id == a)
        inside = PolygonPath(room_a.polygon).contains_point(tuple(probe))
        return (a, b) if inside else (b, a)

    def door_frames(self, wall, doors) -> list:
        """Wooden trims around each doorway: two posts and a head, a little proud of the wall."""
        (xa, ya), (xb, yb) = wall.start, wall.end
        yaw = math.atan2(yb - ya, xb - xa)
        u = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        depth = wall.thickness / 2 + 0.01
        mat = textured(self.wood, (1.0, 0.95, 0.9), roughness=0.5)
        shapes = []
        for d in doors:
            c = np.array([d.center[0], d.center[1], 0.0])
            for side in (-1, 1):
                post = c + u * side * (d.width / 2 + FRAME) + [0, 0, d.height / 2]
                shapes += box_faces(post, [FRAME, depth, d.height / 2], yaw, 0.5, mat)
            head = c + [0, 0, d.height + FRAME]
            shapes += box_faces(head, [d.width / 2 + 2 * FRAME, depth, FRAME], yaw, 0.5, mat)
        return shapes

    def light(self, scene, shadows: bool) -> None:
        """Image-based ambient light from the environment map, a dim sun (it casts the shadows
        of quality "high") and the house's ceiling lights, one or two per room."""
        cubemap = environment_map.cubemap()  # prefiltered once per machine
        for sub in scene.sub_scenes:
            sub.render_system.cubemap = cubemap
        scene.set_ambient_light([0.12, 0.12, 0.12])
        scene.add_directional_light(
            [0.3, 0.2, -1.0],
            [0.5, 0.5, 0.48],
            shadow=shadows,
            shadow_scale=12,
            shadow_map_size=2048,
        )
        for light in self.house.lights:
            scene.add_point_light(light.position, [1.5 * light.intensity + 0.3] * 3, shadow=False)

    # ------------------------------------------------------------------ furniture
    def furniture_model(self, f: Furniture) -> tuple[str, list[float]] | None:
        """(GLB file, scale) for a static piece, None if it keeps dressed primitives."""
        if f.joints or f.type in DRESSING:
            return None
        options = assets.variants("furniture", f.type)
        if not options:
            return None
        rel = pick(options, self.seed, f.id)
        return str(assets.path(rel)), model_scale(rel, f)

    def dressing(self, type_name: str) -> tuple[str, RGB]:
        """Texture and tint of a procedural piece; cabinets take the house's wood."""
        name, tint = DRESSING.get(type_name, (self.wood, (1.0, 1.0, 1.0)))
        if name in WOODS and type_name not in OWN_WOOD:
            name = self.wood
        return name, tint

    def part_material(self, f: Furniture, colour: RGB, link: bool = False):
        """A procedural part's material: the piece's texture, shaded as the part was."""
        if colour in METAL_PARTS:
            return textured(METAL_PARTS[colour], (0.85, 0.86, 0.9), roughness=0.35, metallic=0.6)
        name, tint = self.dressing(f.type)
        base = furniture_colour(f.type)
        ratio = np.mean(colour) / max(np.mean(base), 1e-6)
        if ratio > 1.05 and f.type in TOPS:
            return textured(TOPS[f.type], (0.95, 0.95, 0.93), roughness=0.4)
        shade = float(np.clip(ratio, 0.5, 1.3))
        rgb = tuple(float(min(1.0, t * shade)) for t in tint)
        metallic = 0.5 if name in ("steel", "metal_dark") else 0.0
        return textured(name, rgb, roughness=0.55, metallic=metallic)

    # ------------------------------------------------------------------ objects
    def object_model(self, o: PlacedObject) -> tuple[str, list[float]] | None:
        options = assets.variants("object", o.type)
        if not options:
            return None
        from maniskill_tidy.knowledge import load_catalog

        rel = pick(options, self.seed, o.id)
        size = load_catalog().info(o.type).size or o.size
        return str(assets.path(rel)), [a / b for a, b in zip(o.size, size, strict=True)]
