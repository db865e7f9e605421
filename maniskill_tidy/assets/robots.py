"""v2 robots from the Fetch mobile manipulator bundled in the mani-skill wheel (Apache-2.0).

SAPIEN loads ``fetch.urdf`` with the arm tucked; each robot kind keeps the links it has (a
scout has no arm; the low scout is the bare base), and the assembled mesh is scaled so the base
fits the 0.18 m body radius of the navigation grid and the head sits at the kind's camera
height (``envs/robots.py``). Decimated like every other model; the base wears the kind's
colour, so teammates stay tellable apart.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sapien
import trimesh
from PIL import Image

BASE = ("base_link", "r_wheel_link", "l_wheel_link", "estop_link", "laser_link")
MAST = ("torso_fixed_link", "torso_lift_link", "bellows_link2")
HEAD = ("head_pan_link", "head_tilt_link")
ARM = (
    "shoulder_pan_link",
    "shoulder_lift_link",
    "upperarm_roll_link",
    "elbow_flex_link",
    "forearm_roll_link",
    "wrist_flex_link",
    "wrist_roll_link",
    "gripper_link",
    "r_gripper_finger_link",
    "l_gripper_finger_link",
)
TUCKED = {  # Fetch's usual tuck: the arm folded inside the footprint
    "shoulder_pan_joint": 1.32,
    "shoulder_lift_joint": 1.40,
    "upperarm_roll_joint": -0.2,
    "elbow_flex_joint": 1.72,
    "forearm_roll_joint": 0.0,
    "wrist_flex_joint": 1.66,
    "wrist_roll_joint": 0.0,
}
# kind -> (links, camera height, body radius, base colour); values as in envs/robots.py
KINDS = {
    "manipulator": (BASE + MAST + HEAD + ARM, 1.0, (0.85, 0.15, 0.55)),
    "low_manipulator": (BASE + ARM, 0.25, (0.6, 0.2, 0.85)),
    "high_scout": (BASE + MAST + HEAD, 0.9, (0.15, 0.55, 0.95)),
    "low_scout": (BASE, 0.22, (0.95, 0.55, 0.1)),
}
RADIUS = 0.18
TRIANGLES = {"manipulator": 2500, "low_manipulator": 2000, "high_scout": 1800, "low_scout": 1200}


def fetch_links(urdf: Path) -> dict[str, list[tuple[np.ndarray, np.ndarray, dict]]]:
    """Per link: (vertices in the robot frame, triangles, look) of its visual meshes."""
    scene = sapien.Scene()
    loader = scene.create_urdf_loader()
    loader.fix_root_link = True
    art = loader.load(str(urdf))
    qpos = np.zeros(art.dof)
    for i, j in enumerate(art.get_active_joints()):
        qpos[i] = TUCKED.get(j.name, 0.0)
    art.set_qpos(qpos)
    out = {}
    for link in art.links:
        body = link.entity.find_component_by_type(sapien.render.RenderBodyComponent)
        if body is None:
            continue
        pose = link.entity_pose.to_transformation_matrix()
        meshes = []
        for shape in body.render_shapes:
            local = shape.local_pose.to_transformation_matrix() @ np.diag([*shape.scale, 1.0])
            m = pose @ local
            for part in getattr(shape, "parts", []):
                v = part.vertices @ m[:3, :3].T + m[:3, 3]
                tex = part.material.base_color_texture
                look = {
                    "colour": np.asarray(part.material.base_color[:3]),
                    "image": Image.open(tex.filename) if tex is not None else None,
                    "uv": np.asarray(part.get_vertex_uv(), np.float64) if tex else None,
                    "opacity": 1.0,
                    "normals": part.get_vertex_normal() @ m[:3, :3].T,
                }
                meshes.append((v, np.asarray(part.triangles), look))
        out[link.name] = meshes
    return out


def robot_parts(links: dict, kind: str) -> list[tuple[trimesh.Trimesh, dict]]:
    """The kind's links as (mesh, look) parts, scaled to its radius and camera height."""
    names, camera, colour = KINDS[kind]
    base = np.concatenate([v for v, _, _ in links["base_link"]])
    radius = np.max(np.linalg.norm(base[:, :2], axis=1))
    xy = RADIUS / radius
    chosen = [(name, mesh) for name in names for mesh in links.get(name, [])]
    top = max(v[:, 2].max() for _, (v, _, _) in chosen)
    # the head's top a little above the camera; the bare base: its own proportions
    z = xy if kind == "low_scout" else (camera + 0.06) / top
    parts = []
    for name, (v, tri, look) in chosen:
        mesh = trimesh.Trimesh(v * [xy, xy, z], tri, process=False)
        look = dict(look)
        n = look.pop("normals") / [xy, xy, z]
        mesh.vertex_normals = n / np.linalg.norm(n, axis=1, keepdims=True).clip(1e-9)
        if name == "base_link":  # the kind's colour, plain: the base texture's seams show
            look["image"], look["uv"] = None, None
            look["colour"] = 0.25 + 0.65 * np.asarray(colour)
        parts.append((mesh, look))
    return parts
