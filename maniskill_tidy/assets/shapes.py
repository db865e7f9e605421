"""Textured shapes for the pickupable types no archive has a model of.

Each recipe builds the thing from a few trimesh primitives (a sphere squashed into an egg, a
cup and a stick for a plunger) and wraps them in a tinted robosuite texture (MIT) with
cylindrical UVs, so that at 224 px it reads as what it is, not as a flat-coloured box. Every
recipe gets the object's catalogue size (w, d, h) and fills it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import trimesh
from PIL import Image, ImageDraw

Part = tuple[trimesh.Trimesh, dict]


def _uv(mesh: trimesh.Trimesh) -> np.ndarray:
    """Cylindrical UVs about the mesh's own z axis."""
    v = mesh.vertices - mesh.vertices.mean(0)
    u = np.arctan2(v[:, 1], v[:, 0]) / (2 * math.pi) + 0.5
    z = mesh.vertices[:, 2]
    t = (z - z.min()) / max(z.max() - z.min(), 1e-9)
    return np.stack([u, t], axis=1)


def _part(mesh: trimesh.Trimesh, image: Image.Image | None, colour=(0.8, 0.8, 0.8)) -> Part:
    m = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    uv = _uv(m) if image is not None else None
    return m, {"colour": np.asarray(colour), "image": image, "uv": uv, "opacity": 1.0}


def _tint(image: Image.Image, rgb, strength: float = 1.0) -> Image.Image:
    grey = np.asarray(image.convert("L"), dtype=np.float32)[..., None] / 255.0
    contrast = 0.55 + 0.45 * (grey / max(grey.mean(), 1e-3)).clip(0, 2) / 2
    out = np.asarray(rgb, dtype=np.float32)[None, None] * (contrast * strength)
    return Image.fromarray((out * 255).clip(0, 255).astype(np.uint8))


def fit_into(parts: list[Part], size) -> list[Part]:
    """Scale parts together into the box ``size`` (w, d, h), bottom centre at the origin."""
    verts = np.concatenate([m.vertices for m, _ in parts])
    lo, hi = verts.min(0), verts.max(0)
    scale = np.asarray(size) / np.maximum(hi - lo, 1e-9)
    offset = np.array([-size[0] / 2, -size[1] / 2, 0.0]) - lo * scale
    for m, _ in parts:
        m.vertices = m.vertices * scale + offset
    return parts


def _sphere(radii=(1, 1, 1), centre=(0, 0, 0)) -> trimesh.Trimesh:
    s = trimesh.creation.uv_sphere(radius=1.0, count=[12, 16])
    s.vertices = s.vertices * radii + centre
    return s


def _cylinder(r: float, h: float, z0: float = 0.0, sections: int = 16, axis: str = "z"):
    c = trimesh.creation.cylinder(radius=r, height=h, sections=sections)
    c.vertices[:, 2] += z0 + h / 2
    if axis == "x":
        c.vertices = c.vertices[:, [2, 1, 0]]
    return c


def _texture(d, name: str) -> tuple[Image.Image, dict]:
    return d.texture_source(f"robosuite/{name}")


def _fruit(d, size, rgb, squash, stem_rgb, base="clay"):
    img, credit = _texture(d, base)
    body = _part(_sphere((1, 1, squash)), _tint(img, rgb))
    stem = _part(_cylinder(0.08, 0.25, squash * 0.9), None, stem_rgb)
    return fit_into([body, stem], size), [credit]


def apple(d, size):
    return _fruit(d, size, (0.75, 0.08, 0.06), 0.9, (0.35, 0.22, 0.1))


def tomato(d, size):
    return _fruit(d, size, (0.9, 0.15, 0.08), 0.8, (0.2, 0.5, 0.15))


def potato(d, size):
    img, credit = _texture(d, "dirt")
    return fit_into([_part(_sphere((1.3, 1, 0.8)), _tint(img, (0.75, 0.58, 0.38)))], size), [credit]


def egg(d, size):
    img, credit = _texture(d, "ceramic")
    shell = _part(_sphere((1, 1, 1.35)), _tint(img, (1.0, 0.96, 0.88), 1.15))
    return fit_into([shell], size), [credit]


def lettuce(d, size):
    img, credit = _texture(d, "gray-felt")
    leaves = [
        _part(_sphere((1, 1, 0.9)), _tint(img, (0.45, 0.78, 0.3))),
        _part(_sphere((0.8, 0.9, 0.7), (0.3, 0.1, 0.35)), _tint(img, (0.55, 0.85, 0.35))),
    ]
    return fit_into(leaves, size), [credit]


def _roll(d, size, rgb, texture="white-plaster", hole=True):
    img, credit = _texture(d, texture)
    parts = [_part(_cylinder(1.0, 1.0, 0.0, 20), _tint(img, rgb))]
    if hole:
        parts.append(_part(_cylinder(0.3, 1.01, -0.005, 12), None, (0.55, 0.45, 0.32)))
    return fit_into(parts, size), [credit]


def toilet_paper(d, size):
    return _roll(d, size, (0.97, 0.97, 0.95))


def paper_towel(d, size):
    return _roll(d, size, (0.98, 0.98, 0.96))


def foil(d, size):
    img, credit = _texture(d, "steel-brushed")
    box_img, _ = _texture(d, "white-plaster")
    roll = _part(_cylinder(1.0, 6.0, 0.0, 16, axis="x"), _tint(img, (0.85, 0.86, 0.9)))
    box = _part(trimesh.creation.box((6.2, 2.2, 1.2)), _tint(box_img, (0.2, 0.35, 0.7)))
    box[0].vertices += [3.0, 0, 1.5]
    return fit_into([roll, box], size), [credit]


def bat(d, size):
    img, credit = _texture(d, "light-wood")
    body = _cylinder(1.0, 10.0, 2.0, 16)
    body.vertices[:, :2] *= 0.45 + 0.55 * ((body.vertices[:, 2:3] - 2.0) / 10.0)  # tapered
    handle = _part(_cylinder(0.45, 2.0, 0.0, 12), None, (0.15, 0.12, 0.1))
    return fit_into([_part(body, _tint(img, (0.85, 0.68, 0.45))), handle], size), [credit]


def _flat_image(draw_fn, size=(128, 128), bg=(200, 200, 200)) -> Image.Image:
    img = Image.new("RGB", size, bg)
    draw_fn(ImageDraw.Draw(img), size)
    return img


def cd(d, size):
    def rainbow(draw, s):
        for i in range(32):
            hue = i / 32
            rgb = tuple(int(180 + 60 * math.sin(2 * math.pi * (hue + k / 3))) for k in range(3))
            r = s[0] // 2 - i * 2
            draw.ellipse([s[0] // 2 - r, s[1] // 2 - r, s[0] // 2 + r, s[1] // 2 + r], fill=rgb)

    disc = _part(_cylinder(1.0, 0.05, 0.0, 24), _flat_image(rainbow))
    m, look = disc
    look["uv"] = (m.vertices[:, :2] + 1) / 2  # planar: the image seen from above
    hole = _part(_cylinder(0.15, 0.052, -0.001, 12), None, (0.9, 0.9, 0.92))
    return fit_into([disc, hole], size), [d.own("maniskill_tidy/assets/shapes.py:cd", "CD")]


def card(d, size):
    def face(draw, s):
        draw.rectangle([0, 0, s[0], s[1]], fill=(30, 80, 160))
        draw.rectangle([10, 50, 40, 72], fill=(220, 190, 90))  # chip
        for i in range(4):
            draw.rectangle([10 + 28 * i, 90, 32 + 28 * i, 98], fill=(230, 230, 240))

    m = trimesh.creation.box((1.0, 1.0, 0.02))
    part = _part(m, _flat_image(face))
    part[1]["uv"] = m.vertices[:, :2] + 0.5
    return fit_into([part], size), [d.own("maniskill_tidy/assets/shapes.py:card", "credit card")]


def dumbbell(d, size):
    img, credit = _texture(d, "metal")
    grey = _tint(img, (0.3, 0.3, 0.33))
    parts = [_part(_cylinder(0.25, 8.0, 0.0, 12, axis="x"), grey)]
    for x in (0.3, 6.7):
        p = _part(_cylinder(1.0, 1.0, 0.0, 8, axis="x"), grey)  # octagonal plates
        p[0].vertices[:, 0] += x
        parts.append(p)
    parts = fit_into(parts, (size[1], size[0], size[2]) if size[0] < size[1] else size)
    if size[0] < size[1]:
        for m, _ in parts:
            m.vertices = m.vertices[:, [1, 0, 2]]
    return parts, [credit]


def pillow(d, size):
    img, credit = _texture(d, "gray-felt")
    body = _sphere((1.0, 1.0, 1.0))
    v = body.vertices
    v[:, :2] = np.sign(v[:, :2]) * np.abs(v[:, :2]) ** 0.45  # a cushion: square, puffy
    v[:, 2] *= 0.35 + 0.65 * (1 - np.abs(v[:, 0]) ** 4) * (1 - np.abs(v[:, 1]) ** 4)
    return fit_into([_part(body, _tint(img, (0.85, 0.82, 0.9)))], size), [credit]


def soap(d, size):
    img, credit = _texture(d, "ceramic")
    body = _sphere((1.6, 1.0, 0.6))
    body.vertices[:, :2] = np.sign(body.vertices[:, :2]) * np.abs(body.vertices[:, :2]) ** 0.8
    return fit_into([_part(body, _tint(img, (0.95, 0.72, 0.8)))], size), [credit]


def plunger(d, size):
    wood, credit = _texture(d, "light-wood")
    cup = _sphere((1.0, 1.0, 0.8))
    cup.vertices[:, 2] = np.abs(cup.vertices[:, 2])  # a dome, open side down
    parts = [
        _part(cup, None, (0.6, 0.08, 0.08)),
        _part(_cylinder(0.15, 5.0, 0.6, 10), _tint(wood, (0.8, 0.6, 0.4))),
    ]
    return fit_into(parts, size), [credit]


def watering_can(d, size):
    img, credit = _texture(d, "metal")
    green = _tint(img, (0.25, 0.55, 0.3))
    body = _part(_cylinder(1.0, 1.6, 0.0, 16), green)
    spout = _cylinder(0.12, 1.8, 0.0, 8)
    angle = math.radians(50)
    rot = trimesh.transformations.rotation_matrix(angle, [0, 1, 0])
    spout.apply_transform(rot)
    spout.vertices += [0.8, 0, 0.3]
    handle = trimesh.creation.box((1.2, 0.15, 0.15))
    handle.vertices += [-0.2, 0, 2.0]
    parts = [body, _part(spout, green), _part(handle, green)]
    return fit_into(parts, size), [credit]


SHAPES: dict[str, Callable] = {
    f.__name__: f
    for f in (
        apple,
        tomato,
        potato,
        egg,
        lettuce,
        toilet_paper,
        paper_towel,
        foil,
        bat,
        cd,
        card,
        dumbbell,
        pillow,
        soap,
        plunger,
        watering_can,
    )
}
