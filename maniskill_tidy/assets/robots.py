"""v2's four robot kinds, modelled by the project from trimesh primitives and sweeps.

No robot mesh that installs offline carries a licence this package may ship (Fetch's meshes in
the mani-skill wheel are fetch_ros's CC-BY-NC-SA-4.0), so the robots are built here: a
differential-drive base (shell, bumper, two wheels and a caster), a mast up to a camera head at
the kind's camera height (``envs/robots.py``), and for manipulators a folded arm with a
parallel gripper. Each kind's shell wears its colour, so teammates stay tellable apart.

Everything stays inside the 0.18 m body radius the navigation grid is computed for, and the
arm is folded behind the camera (x at most :data:`ARM_FRONT`), so that a camera tilted fully
down does not see its own arm, as v1's stowed arm. Robots have no collision shapes (collisions
are decided on the grid), so only the look is made here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

Part = tuple[trimesh.Trimesh, dict]

RADIUS = 0.18  # metres: envs/robots.py's RobotKind.radius (AGENT_RADIUS - 0.02)
ARM_FRONT = 0.1  # metres ahead of the centre: the folded arm stays behind this
SHARP = np.radians(35)  # edges sharper than this are shaded flat (box corners, cylinder caps)


@dataclass(frozen=True)
class KindLook:
    """What the look needs of a kind; the values are those of ``envs/robots.py``."""

    camera_height: float
    manipulator: bool
    colour: tuple[float, float, float]
    hold_height: float = 0.7  # where the kind carries a held object


KINDS = {
    "low_scout": KindLook(0.22, False, (0.95, 0.55, 0.1)),
    "high_scout": KindLook(0.9, False, (0.15, 0.55, 0.95)),
    "manipulator": KindLook(1.0, True, (0.85, 0.15, 0.55)),
    "low_manipulator": KindLook(0.25, True, (0.6, 0.2, 0.85), hold_height=0.12),
}
# triangles per kind: the Fetch-derived robots' budgets, which the modelled ones stay under
TRIANGLES = {"manipulator": 2500, "low_manipulator": 2000, "high_scout": 1800, "low_scout": 1200}

# PBR materials (glTF metallic-roughness)
RUBBER = {"colour": (0.06, 0.06, 0.07), "metallic": 0.0, "roughness": 0.9}
DARK = {"colour": (0.16, 0.16, 0.18), "metallic": 0.1, "roughness": 0.55}
ALUMINIUM = {"colour": (0.72, 0.73, 0.75), "metallic": 0.8, "roughness": 0.35}
GLASS = {"colour": (0.02, 0.03, 0.05), "metallic": 0.5, "roughness": 0.08}
LIGHT = {"colour": (0.85, 0.95, 1.0), "metallic": 0.0, "roughness": 0.3}
WHITE = {"colour": (0.86, 0.86, 0.84), "metallic": 0.0, "roughness": 0.45}  # torso shell


def shell(colour) -> dict:
    return {"colour": tuple(colour), "metallic": 0.0, "roughness": 0.4}  # painted plastic


def _shaded(mesh: trimesh.Trimesh, look: dict) -> Part:
    """Flat across sharp edges, smooth elsewhere; the look as ``meshes.part_mesh`` reads it."""
    smooth = trimesh.graph.smooth_shade(mesh, angle=SHARP)
    m = trimesh.Trimesh(smooth.vertices, smooth.faces, process=False)
    # components that should be 0 come out as +-1e-16 noise that differs between machines (the
    # derived bytes with them): 0 they are
    normals = m.vertex_normals.copy()
    normals[np.abs(normals) < 1e-9] = 0.0
    m.vertex_normals = normals
    full = {"image": None, "uv": None, "opacity": 1.0} | look
    return m, full | {"colour": np.asarray(look["colour"], dtype=np.float64)}


def box(lo, hi, look: dict) -> Part:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    return _shaded(m, look)


def rounded_box(lo, hi, radius: float, look: dict, segments: int = 4) -> Part:
    """A box with its vertical edges rounded: the hull of a quarter circle at each corner."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    angles = np.linspace(0.0, np.pi / 2, segments + 1)
    points = []
    for sx, sy, start in ((1, 1, 0.0), (-1, 1, np.pi / 2), (-1, -1, np.pi), (1, -1, 1.5 * np.pi)):
        cx = (hi[0] - radius) if sx > 0 else (lo[0] + radius)
        cy = (hi[1] - radius) if sy > 0 else (lo[1] + radius)
        for a in start + angles:
            for z in (lo[2], hi[2]):
                points.append((cx + radius * np.cos(a), cy + radius * np.sin(a), z))
    return _shaded(trimesh.convex.convex_hull(np.array(points)), look)


def cylinder(r: float, a, b, look: dict, sections: int = 24) -> Part:
    """A cylinder of radius ``r`` from point ``a`` to point ``b``."""
    m = trimesh.creation.cylinder(radius=r, segment=np.array([a, b], float), sections=sections)
    return _shaded(m, look)


def capsule(r: float, a, b, look: dict) -> Part:
    """A link of an arm: a capsule of radius ``r`` from ``a`` to ``b``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    m = trimesh.creation.capsule(height=float(np.linalg.norm(b - a)), radius=r, count=[10, 10])
    m.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], b - a))
    m.apply_translation((a + b) / 2)
    return _shaded(m, look)


def base(kind: KindLook) -> tuple[list[Part], float]:
    """The drive base; returns its parts and its top's height."""
    top = 0.13 if kind.camera_height < 0.5 else 0.2
    paint = shell(kind.colour)
    parts = [
        cylinder(RADIUS - 0.012, (0, 0, 0.07), (0, 0, top - 0.012), paint, sections=28),
        cylinder(RADIUS, (0, 0, 0.045), (0, 0, 0.075), RUBBER, sections=28),  # bumper
        cylinder(RADIUS - 0.03, (0, 0, top - 0.012), (0, 0, top), ALUMINIUM, sections=28),
        cylinder(RADIUS - 0.03, (0, 0, 0.035), (0, 0, 0.045), DARK, sections=20),  # chassis
        cylinder(0.02, (0.12, 0, 0.0), (0.12, 0, 0.04), DARK, sections=8),  # caster
        cylinder(0.02, (-0.12, 0, 0.0), (-0.12, 0, 0.04), DARK, sections=8),
    ]
    for side in (1, -1):  # the drive wheels, their hubs outside
        y = side * 0.125
        parts.append(cylinder(0.05, (0, y - 0.02, 0.05), (0, y + 0.02, 0.05), RUBBER, 20))
        parts.append(cylinder(0.022, (0, y + side * 0.02, 0.05), (0, y + side * 0.024, 0.05),
                              ALUMINIUM, 12))  # fmt: skip
    # a light strip across the front of the shell: where the robot faces
    parts.append(box((0.163, -0.05, top - 0.05), (0.172, 0.05, top - 0.035), LIGHT))
    return parts, top


def head(kind: KindLook, paint: dict) -> list[Part]:
    """A camera head whose lenses sit at the camera height, facing +x."""
    z = kind.camera_height
    parts = [
        rounded_box((0.04, -0.075, z - 0.045), (0.16, 0.075, z + 0.045), 0.025, DARK),
        box((0.045, -0.07, z + 0.045), (0.15, 0.07, z + 0.055), paint),  # a painted cap
        box((0.158, -0.06, z - 0.022), (0.166, 0.06, z + 0.022), GLASS),  # the visor
    ]
    for y in (-0.032, 0.032):  # stereo pair, as a depth camera
        parts.append(cylinder(0.014, (0.164, y, z), (0.172, y, z), ALUMINIUM, 12))
    return parts


def torso(bottom: float, top: float, mast_top: float, x: float = -0.02) -> list[Part]:
    """A torso column on the base, then a slim mast up to the head."""
    return [
        rounded_box((x - 0.075, -0.07, bottom), (x + 0.065, 0.07, top), 0.03, WHITE),
        box((x + 0.064, -0.045, top - 0.09), (x + 0.068, 0.045, top - 0.03), DARK),  # a panel
        cylinder(0.05, (x, 0, top), (x, 0, top + 0.03), DARK, 20),  # the mast's collar
        cylinder(0.03, (x, 0, top + 0.03), (x, 0, mast_top), ALUMINIUM, 16),
    ]


def gripper(wrist, paint: dict) -> list[Part]:
    """A parallel gripper pointing +x from ``wrist``: palm and two fingers."""
    x, y, z = wrist
    return [
        box((x - 0.03, y - 0.035, z - 0.02), (x, y + 0.035, z + 0.02), paint),
        box((x, y + 0.022, z - 0.012), (x + 0.045, y + 0.032, z + 0.012), DARK),
        box((x, y - 0.032, z - 0.012), (x + 0.045, y - 0.022, z + 0.012), DARK),
    ]


def arm(shoulder, elbow, wrist, paint: dict) -> list[Part]:
    """Two links folded at the elbow, joints drawn as dark cylinders across the arm."""
    parts = [capsule(0.032, shoulder, elbow, paint), capsule(0.027, elbow, wrist, paint)]
    for joint, r in ((shoulder, 0.044), (elbow, 0.036)):
        j = np.asarray(joint, float)
        parts.append(cylinder(r, j - [0, 0.035, 0], j + [0, 0.035, 0], DARK, 16))
    return parts + gripper(np.asarray(wrist, float) + [0.03, 0, 0], paint)


def robot_parts(name: str) -> list[Part]:
    """The kind's body in its frame (x forward, z up, origin on the floor under its centre),
    one mesh per material: software rendering pays per draw call as well as per triangle."""
    groups: dict[tuple, list[Part]] = {}
    for mesh, look in _pieces(name):
        key = (*np.round(look["colour"], 4), look.get("metallic"), look.get("roughness"))
        groups.setdefault(key, []).append((mesh, look))
    return [
        (trimesh.util.concatenate([m for m, _ in group]), group[0][1])
        for _, group in sorted(groups.items())
    ]


def _pieces(name: str) -> list[Part]:
    kind = KINDS[name]
    paint = shell(kind.colour)
    parts, top = base(kind)
    z = kind.camera_height
    if z > 0.5:  # the torso up to the arm's shoulder (or a little over half way)
        body_top = kind.hold_height + 0.08 if kind.manipulator else 0.55
        parts += torso(top, body_top, z - 0.04)
    else:  # a short neck up to a low head
        parts.append(box((0.06, -0.03, top), (0.12, 0.03, z - 0.04), DARK))
    parts += head(kind, paint)
    if not kind.manipulator:
        # a lidar puck behind the head
        lidar_z = top if z < 0.5 else z + 0.045
        lidar_x = -0.08 if z < 0.5 else 0.02
        parts.append(cylinder(0.04, (lidar_x, 0, lidar_z), (lidar_x, 0, lidar_z + 0.035), DARK))
        parts.append(cylinder(0.03, (lidar_x, 0, lidar_z + 0.035),
                              (lidar_x, 0, lidar_z + 0.045), GLASS))  # fmt: skip
        return parts
    if z > 0.5:  # a shoulder on the mast's side, the arm folded down and forward
        y = -0.105
        h = kind.hold_height
        shoulder = (-0.02, y, h + 0.03)
        parts += arm(shoulder, (-0.06, y, h - 0.25), (ARM_FRONT - 0.075, y, h - 0.1), paint)
    else:  # a turret at the back of the base, the arm folded over the shell beside the head
        y = 0.11
        parts.append(cylinder(0.035, (-0.05, y, top), (-0.05, y, top + 0.03), DARK, 20))
        shoulder = (-0.05, y, top + 0.05)
        parts += arm(shoulder, (-0.03, y, top + 0.15), (ARM_FRONT - 0.075, y, top + 0.07), paint)
    return parts


def triangles(parts: list[Part]) -> int:
    return sum(len(m.faces) for m, _ in parts)
