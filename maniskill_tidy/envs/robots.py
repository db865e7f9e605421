"""The robot kinds a capability vector (Nav, Mani, Hei) stands for, built from low-poly primitives.

ManiSkill's stock robots carry detailed meshes that software rendering pays for on every frame
(DESIGN.md measured a two-Panda scene at about 245 ms per step), and a full-size Fetch (radius
about 0.28 m) does not fit the 0.2 m agent radius the navigation grid is computed for. These
robots are built from a few boxes and cylinders, with the camera heights of the paper's agents.

Bases move by discrete, grid-aligned steps, so a robot is a kinematic body driven by the action
layer, not a ManiSkill ``BaseAgent`` with continuous controllers; it has no collision shapes,
because collisions with furniture and with other robots are decided on the navigation grid
(see ``envs/actions.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sapien

from maniskill_tidy import assets
from maniskill_tidy.houses.schema import AGENT_RADIUS
from maniskill_tidy.sim.appearance import RGB
from maniskill_tidy.sim.furniture_shapes import Part, box
from maniskill_tidy.sim.house_scene import add_part

Capability = tuple[int, int, int]
STOWED_REACH = 0.1  # metres ahead of the robot's centre: out of view of a camera looking down


@dataclass(frozen=True)
class RobotKind:
    name: str
    camera_height: float  # metres above the floor
    manipulator: bool
    colour: RGB
    radius: float = AGENT_RADIUS - 0.02
    hold_offset: tuple[float, float] = (0.32, 0.7)  # (ahead, height) of a held object's bottom

    @property
    def camera_ahead(self) -> float:
        """Camera sits at the front of the base so that a low camera does not see its own body."""
        return self.radius + 0.02


LOW_SCOUT = RobotKind("low_scout", 0.22, False, (0.95, 0.55, 0.1))
HIGH_SCOUT = RobotKind("high_scout", 0.9, False, (0.15, 0.55, 0.95))
MANIPULATOR = RobotKind("manipulator", 1.0, True, (0.85, 0.15, 0.55))
LOW_MANIPULATOR = RobotKind(
    "low_manipulator", 0.25, True, (0.6, 0.2, 0.85), hold_offset=(0.32, 0.12)
)


def robot_kind(capability: Capability) -> RobotKind:
    """Hei picks the camera height, Mani the arm; every agent navigates (``tasks/teams.py``)."""
    _, mani, hei = capability
    if mani:
        return MANIPULATOR if hei else LOW_MANIPULATOR
    return HIGH_SCOUT if hei else LOW_SCOUT


def robot_parts(kind: RobotKind) -> list[Part]:
    """The body in the robot's frame: x forward, z up, origin on the floor under its centre."""
    r, c = kind.radius, kind.colour
    dark = (0.15, 0.15, 0.17)
    base_h = 0.12 if kind.camera_height < 0.5 else 0.2
    parts = [
        Part("cylinder", (0.0, 0.0, base_h / 2 + 0.02), (r, r, base_h / 2), c),
        Part("cylinder", (0.0, 0.0, 0.02), (r * 0.9, r * 0.9, 0.02), dark),  # wheels skirt
    ]
    cam = kind.camera_height
    if cam > 0.5:  # a mast up to the camera head
        parts.append(box(-0.08, 0.0, -0.04, 0.04, base_h, cam - 0.04, c))
    parts.append(
        box(-0.05, kind.camera_ahead - 0.01, -0.07, 0.07, cam - 0.04, cam + 0.04, dark)
    )  # head
    if kind.manipulator:
        # The arm is stowed against the mast, behind the camera, so that it never hides the
        # floor ahead from its own camera; a held object is carried further out (hold_offset).
        _, z = kind.hold_offset
        arm_z, reach = z - 0.03, STOWED_REACH
        parts += [
            box(-0.02, 0.03, -0.03, 0.03, base_h, arm_z + 0.03, c)
            if cam < 0.5
            else box(-0.02, 0.03, -0.03, 0.03, arm_z - 0.03, arm_z + 0.03, c),
            box(0.0, reach - 0.05, -0.025, 0.025, arm_z - 0.025, arm_z + 0.025, c),  # arm
            box(reach - 0.05, reach - 0.03, -0.07, 0.07, arm_z - 0.03, arm_z + 0.03, dark),
            box(reach - 0.03, reach, -0.07, -0.055, arm_z - 0.02, arm_z + 0.02, dark),  # fingers
            box(reach - 0.03, reach, 0.055, 0.07, arm_z - 0.02, arm_z + 0.02, dark),
        ]
    return parts


def build_robot(scene, name: str, kind: RobotKind, realistic: bool = False) -> sapien.Entity:
    """A kinematic robot in ``scene`` (a ManiSkillScene); returns its SAPIEN entity. v2
    (``realistic``) draws the kind from Fetch's meshes (``assets/robots.py``)."""
    builder = scene.create_actor_builder()
    if realistic:
        builder.add_visual_from_file(str(assets.path(f"robots/{kind.name}.glb")))
    else:
        for part in robot_parts(kind):
            add_part(builder, part, collision=False)
    builder.initial_pose = sapien.Pose(p=[0.0, 0.0, -10.0])
    return builder.build_kinematic(name)


def robot_pose(x: float, y: float, rotation_deg: float) -> sapien.Pose:
    yaw = math.radians(rotation_deg)
    return sapien.Pose(p=[x, y, 0.0], q=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
