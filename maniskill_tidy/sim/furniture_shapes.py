"""Furniture as primitives: a recognisable low-poly body per type, plus its doors and drawers.

Everything is in the piece's local frame (origin at the bottom centre, +y is the front, z up),
sized from the house spec, and shaped so that the spec's surfaces are real: a top surface at
height z has a slab whose top is at z, a compartment has a floor at its surface height and an
open front (behind a door or as a drawer tray), so objects placed by the spec rest on geometry.
Software rendering pays per triangle, so every part is a box, a cylinder or a sphere.
"""

from __future__ import annotations

from dataclasses import dataclass

from maniskill_tidy.houses.schema import Furniture, Joint
from maniskill_tidy.sim.appearance import RGB, furniture_colour, shade

PANEL = 0.02  # thickness of shelves, backs and sides
SLAB = 0.04  # thickness of table and counter tops


@dataclass(frozen=True)
class Part:
    kind: str  # "box", "cylinder" (upright) or "sphere"
    center: tuple[float, float, float]
    half: tuple[float, float, float]  # half extents; cylinder: (r, r, half height); sphere: (r,)*3
    colour: RGB


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, colour: RGB) -> Part:
    """An axis-aligned box from its bounds (degenerate extents are padded to 5 mm)."""
    hx, hy, hz = (max(abs(b - a) / 2, 0.0025) for a, b in ((x0, x1), (y0, y1), (z0, z1)))
    return Part("box", ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2), (hx, hy, hz), colour)


def shell(w: float, d: float, z0: float, z1: float, colour: RGB, x0=None, x1=None) -> list[Part]:
    """A carcass open at the front (+y): back, two sides, bottom and top."""
    x0 = -w / 2 if x0 is None else x0
    x1 = w / 2 if x1 is None else x1
    y0, y1 = -d / 2, d / 2
    return [
        box(x0, x1, y0, y0 + PANEL, z0, z1, colour),
        box(x0, x0 + PANEL, y0, y1, z0, z1, colour),
        box(x1 - PANEL, x1, y0, y1, z0, z1, colour),
        box(x0, x1, y0, y1, z0, z0 + PANEL, colour),
        box(x0, x1, y0, y1, z1 - PANEL, z1, colour),
    ]


def legs(w: float, d: float, z1: float, colour: RGB, t: float = 0.05) -> list[Part]:
    """Four square posts of side ``t`` in the corners of the footprint."""
    return [
        box(x, x + t, y, y + t, 0.0, z1, colour)
        for x in (-w / 2, w / 2 - t)
        for y in (-d / 2, d / 2 - t)
    ]


def slab(w: float, d: float, z: float, colour: RGB, y: float = 0.0) -> Part:
    return box(-w / 2, w / 2, y - d / 2, y + d / 2, z - SLAB, z, colour)


def body_parts(f: Furniture) -> list[Part]:
    """The fixed part of a piece (the root link of an articulated one).

    A catalogue, one branch per furniture type, read as a table: the branches share the
    piece's size and shades, and each is a few boxes; split into functions the shapes of one
    family would sit apart from the measures they use."""
    w, d, h = f.size
    c = furniture_colour(f.type)
    dark, light = shade(c, 0.7), shade(c, 1.15)
    t = f.type
    if t in ("CounterTop", "Sink"):
        cabinet = f.surface("cabinet")
        kick = box(-w / 2, w / 2, -d / 2, -d / 2 + 0.02, 0, 0.1, dark)
        shelf = box(-w / 2, w / 2, -d / 2, d / 2, cabinet.center[2] - PANEL, cabinet.center[2], c)
        if t == "CounterTop":
            return [*shell(w, d, 0.0, h - SLAB, c), kick, shelf, slab(w + 0.02, d + 0.02, h, light)]
        # the basin is a recess: the carcass stops under its floor, the rims reach the top
        basin = f.surface("basin")
        bx, bz = basin.center[0], basin.center[2]
        bw, bd = basin.size
        steel = (0.75, 0.77, 0.8)
        z0 = bz - PANEL
        return [
            *shell(w, d, 0.0, z0, c),
            kick,
            shelf,
            box(-w / 2, bx - bw / 2, -d / 2, d / 2, z0, h, light),
            box(bx + bw / 2, w / 2, -d / 2, d / 2, z0, h, light),
            box(bx - bw / 2, bx + bw / 2, -d / 2, -bd / 2, z0, h, light),
            box(bx - bw / 2, bx + bw / 2, bd / 2, d / 2, z0, h, light),
            box(bx - bw / 2, bx + bw / 2, -bd / 2, bd / 2, z0, bz, steel),
            Part("cylinder", (bx, -d / 2 + 0.05, h + 0.12), (0.015, 0.015, 0.12), steel),
        ]
    if t in ("Fridge", "Safe", "Microwave"):
        parts = shell(w, d, 0.0, h, c)
        for s in f.surfaces:
            parts.append(box(-w / 2, w / 2, -d / 2, d / 2, s.center[2] - PANEL, s.center[2], light))
        if t == "Microwave":  # control panel beside the cooking chamber
            inner = f.surface("inside")
            x = inner.center[0] + inner.size[0] / 2 + 0.02
            parts.append(box(x, w / 2, -d / 2, d / 2, 0, h, dark))
        return parts
    if t == "Dresser":
        return (
            shell(w, d, 0.0, h - SLAB, c)
            + [slab(w + 0.02, d + 0.02, h, light)]
            + [box(-w / 2, w / 2, -d / 2, d / 2, 0, 0.05, dark)]
        )
    if t in ("Desk", "SideTable"):
        j = f.joints[0]
        x0 = j.link_center[0] - j.link_size[0] / 2 - 0.02
        x1 = j.link_center[0] + j.link_size[0] / 2 + 0.02
        z0 = j.link_center[2] - j.link_size[2] / 2 - 0.02
        return [
            slab(w, d, h, light),
            *legs(w, d, h - SLAB, dark),
            *shell(w, d, z0, h - SLAB, c, x0, x1),
        ]
    if t in ("DiningTable", "CoffeeTable", "Stool"):
        return [slab(w, d, h, c), *legs(w, d, h - SLAB, dark)]
    if t == "ShelvingUnit":
        parts = [
            box(-w / 2, w / 2, -d / 2, -d / 2 + PANEL, 0, h, dark),
            box(-w / 2, -w / 2 + PANEL, -d / 2, d / 2, 0, h, c),
            box(w / 2 - PANEL, w / 2, -d / 2, d / 2, 0, h, c),
            box(-w / 2, w / 2, -d / 2, d / 2, 0, 0.05, c),
            slab(w, d, h, c),
        ]
        for s in f.surfaces:
            if s.name != "top":
                parts.append(box(-w / 2, w / 2, -d / 2, d / 2, s.center[2] - PANEL, s.center[2], c))
        return parts
    if t == "Chair":
        seat = f.surface("seat")
        z = seat.center[2]
        return [
            slab(w, d * 0.8, z, c, y=d * 0.1),
            *legs(w, d, z - SLAB, dark, t=0.04),
            box(-w / 2, w / 2, -d / 2, -d / 2 + 0.05, z, h, c),
        ]
    if t in ("Sofa", "ArmChair"):
        seat = f.surface("seat")
        z = seat.center[2]
        back = d * 0.2
        arm = 0.1 if t == "Sofa" else 0.12
        return [
            box(-w / 2, w / 2, -d / 2, d / 2, 0.0, z, c),
            box(-w / 2, w / 2, -d / 2, -d / 2 + back, z, h, dark),
            box(-w / 2, -w / 2 + arm, -d / 2, d / 2, z, z + 0.2, dark),
            box(w / 2 - arm, w / 2, -d / 2, d / 2, z, z + 0.2, dark),
        ]
    if t == "Bed":
        return [
            box(-w / 2, w / 2, -d / 2, d / 2, 0.0, 0.25, dark),
            box(
                -w / 2 + 0.03, w / 2 - 0.03, -d / 2 + 0.05, d / 2 - 0.03, 0.25, h, (0.93, 0.93, 0.9)
            ),
            box(-w / 2, w / 2, -d / 2, -d / 2 + 0.06, 0.0, h + 0.45, c),
            box(
                -w / 2 + 0.03,
                w / 2 - 0.03,
                d / 2 - 0.9,
                d / 2 - 0.03,
                h - 0.02,
                h + 0.001,  # a duvet flush with the mattress: objects on the bed stay in view
                (0.35, 0.5, 0.75),
            ),
        ]
    if t in ("GarbageCan", "LaundryHamper", "Bathtub"):
        inner = f.surfaces[0]
        floor_z = inner.center[2]
        wall = 0.03 if t != "Bathtub" else 0.1
        return [
            box(-w / 2, w / 2, -d / 2, d / 2, 0, floor_z, dark),
            box(-w / 2, w / 2, -d / 2, -d / 2 + wall, 0, h, c),
            box(-w / 2, w / 2, d / 2 - wall, d / 2, 0, h, c),
            box(-w / 2, -w / 2 + wall, -d / 2, d / 2, 0, h, c),
            box(w / 2 - wall, w / 2, -d / 2, d / 2, 0, h, c),
        ]
    if t == "Toilet":
        tank = f.surface("tank")
        ty = tank.center[1] + tank.size[1] / 2 + 0.03
        return [
            box(-w / 2 + 0.05, w / 2 - 0.05, ty, d / 2, 0.0, 0.42, c),
            box(-w / 2 + 0.03, w / 2 - 0.03, ty, d / 2, 0.42, 0.45, shade(c, 0.9)),
            box(-w / 2, w / 2, -d / 2, ty, 0.0, h, c),
        ]
    if t in ("TowelHolder", "HandTowelHolder", "ToiletPaperHanger"):
        return [
            box(-w / 2, w / 2, -0.015, 0.015, h - 0.03, h, c),
            box(-w / 2, -w / 2 + 0.02, -d / 2, 0.0, h - 0.03, h, c),
            box(w / 2 - 0.02, w / 2, -d / 2, 0.0, h - 0.03, h, c),
        ]
    if t == "StoveBurner":
        parts = [box(-w / 2, w / 2, -d / 2, d / 2, 0, h, c)]
        for sx in (-1, 1):
            for sy in (-1, 1):
                parts.append(
                    Part(
                        "cylinder",
                        (sx * w / 4, sy * d / 4, h + 0.005),
                        (0.09, 0.09, 0.005),
                        (0.5, 0.1, 0.05),
                    )
                )
        return parts
    if t == "TVStand":
        return [box(-w / 2, w / 2, -d / 2, d / 2, 0.05, h, c), *legs(w, d, 0.05, dark)]
    if t == "Television":
        return [
            box(-w / 2, w / 2, -0.03, 0.03, 0.12, h, c),
            box(-0.15, 0.15, -d / 2, d / 2, 0.0, 0.02, c),
            box(-0.03, 0.03, -0.02, 0.02, 0.0, 0.12, c),
        ]
    if t == "FloorLamp":
        r = min(w, d) / 2
        return [
            Part("cylinder", (0, 0, 0.015), (r * 0.7, r * 0.7, 0.015), (0.2, 0.2, 0.2)),
            Part("cylinder", (0, 0, h / 2), (0.015, 0.015, h / 2), (0.2, 0.2, 0.2)),
            Part("cylinder", (0, 0, h - 0.15), (r, r, 0.15), c),
        ]
    if t == "HousePlant":
        r = min(w, d) / 2
        pot = 0.35 * h
        return [
            Part("cylinder", (0, 0, pot / 2), (r * 0.6, r * 0.6, pot / 2), (0.6, 0.35, 0.2)),
            Part("sphere", (0, 0, pot + (h - pot) / 2), (min(r, (h - pot) / 2),) * 3, c),
        ]
    return [box(-w / 2, w / 2, -d / 2, d / 2, 0, h, c)]


def link_parts(f: Furniture, j: Joint) -> list[Part]:
    """A door panel with a handle, or an open-topped drawer tray with its front, closed pose."""
    c = shade(furniture_colour(f.type), 0.85)
    handle = (0.25, 0.25, 0.27)
    (cx, cy, cz), (sw, sd, sh) = j.link_center, j.link_size
    x0, x1, y0, y1, z0, z1 = (
        cx - sw / 2,
        cx + sw / 2,
        cy - sd / 2,
        cy + sd / 2,
        cz - sh / 2,
        cz + sh / 2,
    )
    if j.type == "revolute":
        hx = x1 - 0.06 if j.origin[0] <= cx else x0 + 0.06
        return [
            box(x0, x1, y0, y1, z0, z1, c),
            box(
                hx - 0.01,
                hx + 0.01,
                y1,
                y1 + 0.02,
                cz - min(0.1, sh / 4),
                cz + min(0.1, sh / 4),
                handle,
            ),
        ]
    front = f.size[1] / 2
    return [
        box(x0, x1, front - PANEL, front, z0, z1, c),  # drawer front
        box(x0, x1, y0, front, z0, z0 + PANEL, c),  # tray bottom
        box(x0, x1, y0, y0 + PANEL, z0, z1 - 0.02, c),
        box(x0, x0 + PANEL, y0, front, z0, z1 - 0.02, c),
        box(x1 - PANEL, x1, y0, front, z0, z1 - 0.02, c),
        box(cx - 0.06, cx + 0.06, front, front + 0.02, cz - 0.01, cz + 0.01, handle),
    ]
