"""A house spec built into a ManiSkill/SAPIEN scene, and the object bookkeeping on top of it.

Rooms get floors, walls get doorway gaps and lintels, each room its ceiling lights; furniture is
static, or an articulation with real revolute doors and prismatic drawers; objects are dynamic
bodies. Every actor and link is registered as an :class:`Instance` under its SAPIEN
``per_scene_id``, which is the value instance segmentation writes, so every pixel maps back to a
type and an instance id.

Compartments are left open: the paper's action set has no Open/Close, so an object inside a
closed fridge could never be seen or taken out. At every episode start doors stand open at
90 degrees and drawers are pulled out to 60 % of their travel, and the objects in a drawer move
out with it. Open doors and drawers are not obstacles on the navigation grid (which is computed
with them closed); stiff joint drives hold them open, and doors have no collision shapes (a
door opened towards a corner wall would otherwise be pushed back by it).

Objects collide as boxes of their catalogue size even when drawn as spheres or cylinders: a
round apple placed on a table would otherwise roll. Objects hanging on a towel bar or a paper
hanger are kinematic, since a bar cannot hold a box against gravity in a rigid-body simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sapien
from matplotlib.path import Path as PolygonPath

from maniskill_tidy.houses.objects import is_hanging
from maniskill_tidy.houses.schema import Furniture, House, PlacedObject
from maniskill_tidy.knowledge import FLOOR
from maniskill_tidy.sim.appearance import (
    DEFAULT_FLOOR,
    FLOOR_COLOURS,
    RGB,
    WALL_COLOUR,
    object_look,
)
from maniskill_tidy.sim.furniture_shapes import Part, body_parts, link_parts
from maniskill_tidy.sim.realistic import RealisticLook, attach
from maniskill_tidy.sim.visibility import FloorPlan

DOOR_OPEN = math.pi / 2  # radians, clipped to the joint's limit
DRAWER_OPEN = 0.6  # fraction of the drawer's travel
SETTLE_STEPS = 40  # physics steps (at 100 Hz) after objects are placed or released
MOVED = 0.03  # metres: an object that moved more than this while settling was not at rest
OBJECT_DENSITY = 300.0

_UPRIGHT = sapien.Pose(q=[math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0])  # SAPIEN cylinders lie on x


@dataclass(frozen=True)
class Instance:
    """What a segmentation id shows."""

    seg_id: int
    kind: str  # "object", "furniture", "wall", "floor", "robot"
    type: str  # object or furniture type, room type for floors, "Wall", robot kind
    id: str  # object id, furniture id (with "/link" for a door or drawer), wall id, agent name


@dataclass
class ObjectState:
    """Where an object is, logically: the receptacle D judges, or held by an agent."""

    receptacle: str  # furniture id, "Floor", or "held"
    surface: str | None
    room: str | None
    holder: str | None = None


def material(colour: RGB) -> sapien.render.RenderMaterial:
    return sapien.render.RenderMaterial(base_color=[*colour, 1.0], roughness=0.8, metallic=0.0)


def add_part(builder, part: Part, collision: bool = True, visual=True, mat=None) -> None:
    """A primitive's visual (``mat`` or its flat colour; none if ``visual`` is False) and its
    collision shape."""
    pose = sapien.Pose(p=list(part.center))
    mat = mat or material(part.colour)
    if part.kind == "box":
        if visual:
            builder.add_box_visual(pose=pose, half_size=list(part.half), material=mat)
        if collision:
            builder.add_box_collision(pose=pose, half_size=list(part.half))
    elif part.kind == "cylinder":
        cyl = pose * _UPRIGHT
        if visual:
            builder.add_cylinder_visual(
                pose=cyl, radius=part.half[0], half_length=part.half[2], material=mat
            )
        if collision:
            builder.add_cylinder_collision(pose=cyl, radius=part.half[0], half_length=part.half[2])
    elif part.kind == "sphere":
        if visual:
            builder.add_sphere_visual(pose=pose, radius=part.half[0], material=mat)
        if collision:
            builder.add_sphere_collision(pose=pose, radius=part.half[0])
    else:
        raise ValueError(f"unknown part kind {part.kind!r}; expected box, cylinder or sphere")


def yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


def rectilinear_strips(polygon: list[list[float]]) -> list[tuple[float, float, float, float]]:
    """Cover a rectilinear polygon with axis-aligned rectangles (x0, y0, x1, y1)."""
    xs = sorted({p[0] for p in polygon})
    ys = sorted({p[1] for p in polygon})
    outline = PolygonPath(polygon)
    return [
        (x0, y0, x1, y1)
        for x0, x1 in zip(xs, xs[1:], strict=False)
        for y0, y1 in zip(ys, ys[1:], strict=False)
        if outline.contains_point(((x0 + x1) / 2, (y0 + y1) / 2))
    ]


def open_position(j) -> float:
    """The joint position episodes start at: doors swung open, drawers pulled out."""
    if j.type == "revolute":
        return min(DOOR_OPEN, j.limits[1])
    return DRAWER_OPEN * j.limits[1]


class HouseScene:
    """Builds ``house`` into ``scene`` (a ManiSkillScene) once; episodes then only move objects."""

    def __init__(self, scene, house: House, shadows: bool = False, realistic: bool = False) -> None:
        """``realistic``: the v2 look (``sim/realistic.py``); else v1's flat colours."""
        self.scene, self.house, self.shadows = scene, house, shadows
        self.look = RealisticLook(house) if realistic else None
        self.ceilings: list[sapien.Entity] = []
        self.plan = FloorPlan(house)
        self._room_bodies: dict[str, list] = {r.id: [] for r in house.rooms}  # never move
        self.instances: dict[int, Instance] = {}
        self.objects: dict[str, sapien.Entity] = {}
        self.bodies: dict[str, sapien.physx.PhysxRigidDynamicComponent] = {}
        self.articulations: dict[str, sapien.physx.PhysxArticulation] = {}
        self.state: dict[str, ObjectState] = {}
        self.furniture = house.furniture_by_id()
        self.room_type = {r.id: r.type for r in house.rooms}
        self._build()

    # ------------------------------------------------------------------ building
    def _register(
        self, entity: sapien.Entity, kind: str, type_: str, id_: str, room: str | None = None
    ) -> None:
        sid = entity.per_scene_id
        self.instances[sid] = Instance(sid, kind, type_, id_)
        body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
        if room in self._room_bodies and body is not None:
            self._room_bodies[room].append(body)

    # ------------------------------------------------------------------ hiding rooms
    def room_groups(self, movers: dict[str, sapien.Entity]) -> dict[str, list]:
        """Render bodies per room: floors, ceilings, furniture, and ``movers`` (objects,
        robots) by where they are now. Walls are never hidden; a mover outside every room
        neither."""
        groups = {rid: list(bodies) for rid, bodies in self._room_bodies.items()}
        for entity in movers.values():
            rid = self.plan.room_at(entity.get_pose().p)
            body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
            if rid is not None and body is not None:
                groups[rid].append(body)
        return groups

    @staticmethod
    def show_rooms(groups: dict[str, list], visible: set[str] | None) -> None:
        """Hide every group outside ``visible`` (None: show all) for the next picture."""
        for rid, bodies in groups.items():
            v = 1.0 if visible is None or rid in visible else 0.0
            for body in bodies:
                body.visibility = v

    def _raw(self, actor) -> sapien.Entity:
        return actor._objs[0]

    def _build(self) -> None:
        self._build_floors()
        self._build_walls()
        self._build_lights()
        for f in self.house.furniture:
            self._build_furniture(f)
        for o in self.house.objects:
            self._build_object(o)

    def _build_floors(self) -> None:
        for room in self.house.rooms:
            b = self.scene.create_actor_builder()
            colour = FLOOR_COLOURS.get(room.type, DEFAULT_FLOOR)
            strips = rectilinear_strips(room.polygon)
            for x0, y0, x1, y1 in strips:
                part = Part(
                    "box",
                    ((x0 + x1) / 2, (y0 + y1) / 2, -0.05),
                    ((x1 - x0) / 2, (y1 - y0) / 2, 0.05),
                    colour,
                )
                add_part(b, part, visual=self.look is None)
            b.initial_pose = sapien.Pose()
            entity = self._raw(b.build_static(f"floor_{room.id}"))
            if self.look:
                attach(entity, self.look.floor_shapes(room, strips))
            self._register(entity, "floor", room.type, room.id, room=room.id)

    def build_ceilings(self) -> None:
        """v2: a ceiling per room, built last so that every other segmentation id is v1's.
        Agent cameras see it; ``set_ceilings_visible`` hides it for the third-person view."""
        if not self.look:
            return
        height = max((w.height for w in self.house.walls), default=2.6)
        for room in self.house.rooms:
            b = self.scene.create_actor_builder()
            b.initial_pose = sapien.Pose()
            entity = self._raw(b.build_static(f"ceiling_{room.id}"))
            strips = rectilinear_strips(room.polygon)
            attach(entity, self.look.ceiling_shapes(room, strips, height))
            self._register(entity, "ceiling", room.type, room.id, room=room.id)
            self.ceilings.append(entity)

    def set_ceilings_visible(self, visible: bool) -> None:
        for entity in self.ceilings:
            entity.find_component_by_type(sapien.render.RenderBodyComponent).visibility = float(
                visible
            )

    def _build_walls(self) -> None:
        doors_on: dict[str, list] = {}
        for d in self.house.doors:
            doors_on.setdefault(d.wall, []).append(d)
        for wall in self.house.walls:
            (xa, ya), (xb, yb) = wall.start, wall.end
            length = math.hypot(xb - xa, yb - ya)
            if length < 1e-6:
                continue
            ux, uy = (xb - xa) / length, (yb - ya) / length
            spans = [(0.0, length, 0.0, wall.height)]
            for d in sorted(
                doors_on.get(wall.id, []),
                key=lambda d: (d.center[0] - xa) * ux + (d.center[1] - ya) * uy,
            ):
                t = (d.center[0] - xa) * ux + (d.center[1] - ya) * uy
                lo, hi = t - d.width / 2, t + d.width / 2
                new = []
                for s0, s1, z0, z1 in spans:
                    if z0 > 0 or hi <= s0 or lo >= s1:
                        new.append((s0, s1, z0, z1))
                        continue
                    if lo > s0:
                        new.append((s0, lo, z0, z1))
                    if hi < s1:
                        new.append((hi, s1, z0, z1))
                    new.append((max(lo, s0), min(hi, s1), min(d.height, z1), z1))
                spans = new
            b = self.scene.create_actor_builder()
            yaw = math.atan2(uy, ux)
            boxes = []
            for s0, s1, z0, z1 in spans:
                if s1 - s0 < 1e-4 or z1 - z0 < 1e-4:
                    continue
                mid = (s0 + s1) / 2
                centre = [xa + ux * mid, ya + uy * mid, (z0 + z1) / 2]
                pose = sapien.Pose(p=centre, q=yaw_quat(yaw))
                half = [(s1 - s0) / 2, wall.thickness / 2, (z1 - z0) / 2]
                if self.look is None:
                    b.add_box_visual(pose=pose, half_size=half, material=material(WALL_COLOUR))
                b.add_box_collision(pose=pose, half_size=half)
                boxes.append((np.array(centre), half, yaw))
            b.initial_pose = sapien.Pose()
            entity = self._raw(b.build_static(wall.id))
            if self.look:
                frames = self.look.door_frames(wall, doors_on.get(wall.id, []))
                attach(entity, self.look.wall_shapes(wall, boxes) + frames)
            self._register(entity, "wall", "Wall", wall.id)

    def _build_lights(self) -> None:
        """Ambient, a sun-like directional light and the ceiling lights. With shadows ("high"
        quality) the directional light casts them: point-light shadows cost a cube map each and
        measured about 1 step/s for Setting I on 2 cores, too slow to use. v2 adds image-based
        ambient light from an environment map and dims the flat ambient term to match."""
        if self.look:
            self.look.light(self.scene, self.shadows)
            return
        self.scene.set_ambient_light([0.35, 0.35, 0.35])
        self.scene.add_directional_light(
            [0.3, 0.2, -1.0],
            [0.6, 0.6, 0.6],
            shadow=self.shadows,
            shadow_scale=12,
            shadow_map_size=2048,
        )
        for light in self.house.lights:
            colour = [1.6 * light.intensity + 0.4] * 3
            self.scene.add_point_light(light.position, colour, shadow=False)

    def _furniture_pose(self, f: Furniture) -> sapien.Pose:
        return sapien.Pose(p=list(f.position), q=yaw_quat(f.yaw))

    def _build_furniture(self, f: Furniture) -> None:
        look = self.look
        if not f.joints:
            b = self.scene.create_actor_builder()
            model = look.furniture_model(f) if look else None
            if model:
                b.add_visual_from_file(model[0], scale=model[1])
            for part in body_parts(f):
                dress = look.part_material(f, part.colour) if look else None
                add_part(b, part, visual=model is None, mat=dress)
            b.initial_pose = self._furniture_pose(f)
            self._register(self._raw(b.build_static(f.id)), "furniture", f.type, f.id, room=f.room)
            return
        ab = self.scene.create_articulation_builder()
        ab.initial_pose = self._furniture_pose(f)
        root = ab.create_link_builder()
        root.set_name("body")
        for part in body_parts(f):
            add_part(root, part, mat=look.part_material(f, part.colour) if look else None)
        for j in f.joints:
            link = ab.create_link_builder(root)
            link.set_name(j.name)
            link.set_joint_name(j.name)
            axis_q = (
                [math.sqrt(0.5), 0.0, -math.sqrt(0.5), 0.0]
                if j.type == "revolute"
                else [math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]
            )
            link.set_joint_properties(
                j.type,
                [list(j.limits)],
                pose_in_parent=sapien.Pose(p=list(j.origin), q=axis_q),
                pose_in_child=sapien.Pose(q=axis_q),
                friction=0.0,
                damping=10.0,
            )
            for part in link_parts(f, j):
                moved = Part(
                    part.kind,
                    tuple(c - o for c, o in zip(part.center, j.origin, strict=True)),
                    part.half,
                    part.colour,
                )
                # doors are drawn but do not collide: open at 90 degrees a door may touch a wall
                dress = look.part_material(f, part.colour, link=True) if look else None
                add_part(link, moved, collision=j.type != "revolute", mat=dress)
        art = ab.build(name=f.id, fix_root_link=True)
        raw = art._objs[0]
        for joint in raw.get_active_joints():  # stiff drives hold doors and drawers in place
            joint.set_drive_property(stiffness=1e5, damping=1e3)
        self.articulations[f.id] = raw
        prefix = f"scene-0-{f.id}_"  # ManiSkill names links scene-<i>-<articulation>_<link>
        for link in raw.links:
            short = link.entity.name.removeprefix(prefix)
            id_ = f.id if short == "body" else f"{f.id}/{short}"
            self._register(link.entity, "furniture", f.type, id_, room=f.room)

    def _build_object(self, o: PlacedObject) -> None:
        shape, colour = object_look(o.type)
        w, d, h = o.size
        b = self.scene.create_actor_builder()
        mat = material(colour)
        centre = sapien.Pose(p=[0.0, 0.0, h / 2])
        model = self.look.object_model(o) if self.look else None
        if model:
            b.add_visual_from_file(model[0], scale=model[1])
        elif shape == "sphere":
            b.add_sphere_visual(pose=centre, radius=min(w, d, h) / 2, material=mat)
        elif shape == "cylinder":
            b.add_cylinder_visual(
                pose=centre * _UPRIGHT, radius=min(w, d) / 2, half_length=h / 2, material=mat
            )
        else:
            b.add_box_visual(pose=centre, half_size=[w / 2, d / 2, h / 2], material=mat)
        b.add_box_collision(pose=centre, half_size=[w / 2, d / 2, h / 2], density=OBJECT_DENSITY)
        b.initial_pose = sapien.Pose(p=list(o.position), q=yaw_quat(o.yaw))
        actor = b.build(o.id)
        entity = self._raw(actor)
        self.objects[o.id] = entity
        self.bodies[o.id] = entity.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
        self._register(entity, "object", o.type, o.id)

    # ------------------------------------------------------------------ episodes
    def open_compartments(self) -> None:
        for fid, art in self.articulations.items():
            f = self.furniture[fid]
            q = [open_position(j) for j in f.joints]
            art.set_qpos(np.array(q, dtype=np.float32))
            art.set_qvel(np.zeros(len(f.joints), dtype=np.float32))
            for joint, target in zip(art.get_active_joints(), q, strict=True):
                joint.set_drive_target(target)

    def surface_offset(self, f: Furniture, link: str) -> np.ndarray:
        """World displacement of what a drawer carries, with the drawer open."""
        if link == "body":
            return np.zeros(3)
        j = next(j for j in f.joints if j.name == link)
        if j.type != "prismatic":
            return np.zeros(3)
        q = open_position(j)
        ax, ay = j.axis[0], j.axis[1]
        c, s = math.cos(f.yaw), math.sin(f.yaw)
        return np.array([q * (c * ax - s * ay), q * (s * ax + c * ay), 0.0])

    def place_objects(self, house: House) -> None:
        """Put every object where ``house`` (the task's messy house) says, open, and at rest."""
        self.open_compartments()
        for o in house.objects:
            offset = np.zeros(3)
            if o.receptacle != FLOOR:
                f = self.furniture[o.receptacle]
                offset = self.surface_offset(f, f.surface(o.surface).link)
            self.set_object_pose(o.id, np.asarray(o.position) + offset, o.yaw)
            hanging = o.receptacle != FLOOR and is_hanging(
                self.furniture[o.receptacle].surface(o.surface)
            )
            self.bodies[o.id].kinematic = hanging
            self.state[o.id] = ObjectState(o.receptacle, o.surface, o.room)

    def set_object_pose(self, oid: str, bottom: np.ndarray, yaw: float) -> None:
        body = self.bodies[oid]
        self.objects[oid].set_pose(sapien.Pose(p=[float(v) for v in bottom], q=yaw_quat(yaw)))
        if not body.kinematic:
            body.set_linear_velocity([0.0, 0.0, 0.0])
            body.set_angular_velocity([0.0, 0.0, 0.0])

    def object_bottom(self, oid: str) -> np.ndarray:
        return np.asarray(self.objects[oid].get_pose().p, dtype=np.float64)

    def settle(self, steps: int = SETTLE_STEPS, watch: list[str] | None = None) -> list[str]:
        """Step physics; return the watched objects (default: all free ones) that moved more than
        ``MOVED`` (fell, slid or were pushed out of a wrong overlap)."""
        watch = [
            o
            for o in (watch if watch is not None else self.objects)
            if not self.bodies[o].kinematic
        ]
        before = {o: self.object_bottom(o) for o in watch}
        px = self.scene.px
        for _ in range(steps):
            px.step()
        return [o for o in watch if np.linalg.norm(self.object_bottom(o) - before[o]) > MOVED]

    def yaw_of(self, oid: str) -> float:
        q = self.objects[oid].get_pose().q
        return 2.0 * math.atan2(q[3], q[0])
