"""``maniskill-tidy derive-assets``: the offline sources -> the package's v2 asset set.

Reads ``selection.toml`` (what dresses what), the Sweet Home 3D furniture archives, the
robosuite wheel's textures and the installed mani-skill wheel's files, and writes
``assets/data/``: one GLB per model variant (decimated, UVs kept, textures downscaled, scaled to
the nominal size of the type it dresses), PNG textures for rooms and procedural parts, a small
environment map, ``manifest.json`` (source, licence, author, sha256, triangles per file) and
``ATTRIBUTION.md``. Deterministic: the same sources give the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from tqdm import tqdm

from maniskill_tidy.assets import ASSET_DIR, SELECTION
from maniskill_tidy.assets.licences import ALLOWED, NAMES, URIS, check, identify
from maniskill_tidy.assets.meshes import (
    budget_split,
    decimate,
    downscale,
    glb_bytes,
    image_png,
    load_obj,
    part_mesh,
)
from maniskill_tidy.assets.shapes import SHAPES, fit_into
from maniskill_tidy.assets.sources import Sh3fArchive, WheelFiles
from maniskill_tidy.houses.furniture import TEMPLATES, parts_for
from maniskill_tidy.knowledge import load_catalog

FURNITURE_TRIANGLES = 1500
OBJECT_TRIANGLES = 300
FURNITURE_TEXTURE = 256  # px, longest side
OBJECT_TEXTURE = 128
ROOM_TEXTURE = 256
ALLOWED_LICENCES = ALLOWED
DEFAULT_SH3D = Path("/usr/share/sweethome3d/furniture")
PROJECT_LICENCE = Path(__file__).parents[2] / "LICENSE"
KINDS = ("furniture", "objects", "robots", "textures", "environment")
OWN = ("robots/", "environment.hdr")  # files the project models from no source


@dataclass
class Derivation:
    sh3d: Path
    robosuite: Path
    out: Path = ASSET_DIR
    only: set[str] | None = None  # asset paths to derive (tests); None: all
    manifest: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.selection = tomllib.loads(SELECTION.read_text())
        self.sources = self.selection["sources"]
        self.archives: dict[str, Sh3fArchive] = {}
        self.wheel: WheelFiles | None = None
        self.tmp = Path(tempfile.mkdtemp(prefix="derive-assets-"))

    # ------------------------------------------------------------------ sources
    def archive(self, label: str) -> Sh3fArchive:
        if label not in self.archives:
            self.archives[label] = Sh3fArchive(self.sh3d / self.sources[label]["archive"], label)
        return self.archives[label]

    def texture_source(self, ref: str) -> tuple[Image.Image, dict]:
        label, name = ref.split("/", 1)
        if label != "robosuite":
            raise ValueError(f"texture {ref!r}: expected robosuite/NAME")
        if self.wheel is None:
            self.wheel = WheelFiles(self.robosuite)
        inner = f"robosuite/models/assets/textures/{name}.png"
        credit = {k: v for k, v in self.wheel.credit().items() if k != "licence_text"}
        work = {"source": label, "model": inner, "title": f"{name} texture"}
        work["author"] = credit.get("holder", label)
        return Image.open(self.wheel.file(inner)), work | credit

    def own(self, model: str, name: str) -> dict:
        """A file the project models itself, under the licence of the project's own LICENSE."""
        if not PROJECT_LICENCE.is_file():
            raise FileNotFoundError(f"{PROJECT_LICENCE}: the project's LICENSE is missing; "
                                    "derive-assets runs from a checkout")  # fmt: skip
        spdx = check(identify(PROJECT_LICENCE.read_text()), name, "LICENSE")
        return {"source": "maniskill-tidy", "model": model, "title": name,
                "author": "maniskill-tidy contributors", "licence": spdx,
                "licence_file": "LICENSE"}  # fmt: skip

    def model_parts(self, ref: str, box: np.ndarray) -> tuple[list, dict]:
        """A catalog model fitted into ``box`` (x0, y0, z0, x1, y1, z1, metres)."""
        label, stem = ref.split("/", 1)
        arc = self.archive(label)
        model = arc.model(stem)
        obj = arc.extract(model, self.tmp / label)
        parts = load_obj(obj, model.rotation)
        lo = np.min([m.vertices.min(0) for m, _ in parts], axis=0)
        hi = np.max([m.vertices.max(0) for m, _ in parts], axis=0)
        scale = (box[3:] - box[:3]) / np.maximum(hi - lo, 1e-9)
        offset = box[:3] - lo * scale
        for m, _ in parts:
            m.vertices = m.vertices * scale + offset
            normals = m.vertex_normals / np.where(scale == 0, 1, scale)  # inverse transpose
            m.vertex_normals = normals / np.linalg.norm(normals, axis=1, keepdims=True).clip(1e-9)
        return parts, {"source": label, "model": model.path} | arc.credit(model)

    # ------------------------------------------------------------------ writing
    def write(self, rel: str, data: bytes, entry: dict) -> None:
        path = self.out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        self.manifest[rel] = entry | {"sha256": hashlib.sha256(data).hexdigest()}

    def wanted(self, rel: str) -> bool:
        return self.only is None or rel in self.only

    def mesh_file(self, rel: str, parts: list, budget: int, texture: int, entry: dict) -> None:
        counts = [len(m.faces) for m, _ in parts]
        meshes = []
        for (m, look), target in zip(parts, budget_split(counts, budget), strict=True):
            corners, normals, uvs = decimate(m, look["uv"], target)
            if len(corners):
                meshes.append(part_mesh(corners, normals, uvs, look, texture))
        verts = np.concatenate([m.vertices for m in meshes])
        size = (verts.max(0) - verts.min(0)).round(4).tolist()
        entry = entry | {"triangles": int(sum(len(m.faces) for m in meshes)), "size": size}
        self.write(rel, glb_bytes(meshes), entry)

    # ------------------------------------------------------------------ asset kinds
    def furniture(self) -> None:
        for type_name, variants in tqdm(self.selection["furniture"].items(), desc="furniture"):
            w, d, h = nominal_size(type_name)
            for variant in variants:
                if isinstance(variant, str):
                    name = variant.split("/", 1)[1]
                    pieces = [{"model": variant, "box": [0, 0, 0, 1, 1, 1]}]
                else:
                    pieces = variant["parts"]
                    name = "+".join(p["model"].split("/", 1)[1] for p in pieces)
                rel = f"furniture/{type_name}/{name}.glb"
                if not self.wanted(rel):
                    continue
                parts, credits, fit = [], [], {}
                for p in pieces:
                    frac = np.asarray(p["box"], dtype=np.float64)
                    height = h
                    if len(pieces) == 1:
                        # what rests on the piece must stay in view: its surfaces under the spec's
                        got_parts, credit = self.model_parts(p["model"], unit_box(w, d, 1.0))
                        height, fit = surface_safe_height(got_parts, type_name, [w, d, h])
                        for m, _ in got_parts:
                            m.vertices[:, 2] *= height
                    else:
                        box = np.array([w, d, h, w, d, h]) * frac - [w / 2, d / 2, 0] * 2
                        got_parts, credit = self.model_parts(p["model"], box)
                    parts += got_parts
                    credits.append(credit)
                entry = {
                    "kind": "furniture",
                    "type": type_name,
                    "nominal_size": [w, d, h],
                    "surface_fit": fit,
                    "sources": credits,
                }
                self.mesh_file(rel, parts, FURNITURE_TRIANGLES, FURNITURE_TEXTURE, entry)

    def objects(self) -> None:
        catalog = load_catalog()
        for type_name, variants in tqdm(self.selection["objects"].items(), desc="objects"):
            w, d, h = catalog.info(type_name).size
            for variant in variants:
                label, name = variant.split("/", 1) if "/" in variant else variant.split(":", 1)
                rel = f"objects/{type_name}/{name}.glb"
                if not self.wanted(rel):
                    continue
                if variant.startswith("shape:"):
                    parts, credits = SHAPES[name](self, (w, d, h))
                else:
                    parts, credit = self.model_parts(variant, unit_box(1.0, 1.0, 1.0))
                    credits = [credit]
                    fit_object(parts, (w, d, h))
                entry = {"kind": "object", "type": type_name, "sources": credits}
                self.mesh_file(rel, parts, OBJECT_TRIANGLES, OBJECT_TEXTURE, entry)

    def robots(self) -> None:
        from maniskill_tidy.assets import robots

        for kind in tqdm(robots.KINDS, desc="robots"):
            rel = f"robots/{kind}.glb"
            if not self.wanted(rel):
                continue
            parts = robots.robot_parts(kind)
            if robots.triangles(parts) > robots.TRIANGLES[kind]:  # never decimated: modelled
                raise ValueError(f"robot {kind}: {robots.triangles(parts)} triangles, over "
                                 f"its budget of {robots.TRIANGLES[kind]}")  # fmt: skip
            credit = self.own("maniskill_tidy/assets/robots.py", name=f"{kind} robot")
            entry = {"kind": "robot", "type": kind, "sources": [credit]}
            self.mesh_file(rel, parts, robots.TRIANGLES[kind], FURNITURE_TEXTURE, entry)

    def textures(self) -> None:
        for name, spec in tqdm(self.selection["textures"].items(), desc="textures"):
            rel = f"textures/{name}.png"
            if not self.wanted(rel):
                continue
            image, credit = self.texture_source(spec["from"])
            image = downscale(image, ROOM_TEXTURE)
            if "grid" in spec:
                image = grout(image, int(spec["grid"]))
            self.write(rel, image_png(image), {"kind": "texture", "sources": [credit]})

    def environment(self) -> None:
        import cv2

        from maniskill_tidy.assets.lighting import room_map

        rel = "environment.hdr"
        if not self.wanted(rel):
            return
        width, height = self.selection["environment"]["size"]
        ok, data = cv2.imencode(".hdr", room_map(width, height)[..., ::-1])  # cv2 wants BGR
        if not ok:
            raise RuntimeError("cannot encode the environment map as .hdr")
        credit = self.own("maniskill_tidy/assets/lighting.py", "room environment map")
        self.write(rel, data.tobytes(), {"kind": "environment", "sources": [credit]})

    def run(self, kinds: tuple[str, ...] = KINDS) -> dict:
        """Derive into a fresh folder, then swap it in: a failed run leaves the old set. A
        partial run (``only``, tests) opens only the sources its files need."""
        if self.only is None or not all(r.startswith(OWN) for r in self.only):
            for label, src in self.sources.items():  # every source there before any work
                if src.get("archive", "").endswith(".sh3f"):
                    self.archive(label)
            self.wheel = self.wheel or WheelFiles(self.robosuite)
        final, staged = self.out, self.only is None  # a partial run (tests) writes in place
        if staged:
            self.out = final.with_name(f".{final.name}.new")
            shutil.rmtree(self.out, ignore_errors=True)
        try:
            for kind in kinds:
                getattr(self, kind)()
            write_manifest(self.out, self.manifest)
            notices = {}  # MIT: its text travels with the work
            if self.wheel is not None:
                wheel = self.wheel.credit()
                notices[wheel["licence"]] = wheel["licence_text"]
            (self.out / "ATTRIBUTION.md").write_text(attribution(self.manifest, notices))
            if staged:
                shutil.rmtree(final, ignore_errors=True)
                self.out.replace(final)
        finally:  # a failed run leaves neither its staging folder nor its temporary files
            shutil.rmtree(self.tmp, ignore_errors=True)
            if self.wheel is not None:
                shutil.rmtree(self.wheel.tmp, ignore_errors=True)
            if staged:
                shutil.rmtree(self.out, ignore_errors=True)
            self.out = final
        return self.manifest


def unit_box(w: float, d: float, h: float) -> np.ndarray:
    return np.array([-w / 2, -d / 2, 0.0, w / 2, d / 2, h])


def nominal_size(type_name: str) -> list[float]:
    """The middle of the type's size ranges (``houses/furniture.py``)."""
    return [round((lo + hi) / 2, 3) for lo, hi in TEMPLATES[type_name].size]


SURFACE_MARGIN = 0.015  # metres: a model's support surface lies this far under the spec's
SURFACE_QUANTILE = 90  # of the heights the model shows over the middle of a surface
SURFACE_SPAN = 0.4  # half-width of that middle, as a fraction of the surface's size
OPEN_TO_FLOOR = 0.1  # a surface whose model top is this low (fraction) is open to the floor
MIN_SQUASH = 0.6  # a model is never scaled below this fraction of its type's height


def surface_safe_height(parts: list, type_name: str, size: list[float]) -> tuple[float, dict]:
    """The height to scale a model (fitted to unit height) to, so that over each of the
    piece's surfaces (the middle 80 %, sampled from above) 95 % of the model lies at least
    ``SURFACE_MARGIN`` under the height the spec puts objects at: a thin object on a cushion or
    a mattress is not swallowed by it. Without surfaces: the type's height. Returns the height
    and, per surface, the model's top there (fraction of its height) and the scale it asked."""
    import open3d as o3d

    surfaces, _ = parts_for(type_name, size)
    body = [s for s in surfaces if s.link == "body"]
    if not body:
        return size[2], {}
    verts = np.concatenate([m.vertices for m, _ in parts]).astype(np.float32)
    offset = np.cumsum([0] + [len(m.vertices) for m, _ in parts[:-1]])
    faces = np.concatenate([m.faces + o for (m, _), o in zip(parts, offset, strict=True)])
    caster = o3d.t.geometry.RaycastingScene()
    caster.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(faces.astype(np.uint32)))
    asks, fit = [], {}
    for s in body:
        (cx, cy, z), (sw, sd) = s.center, s.size
        gx, gy = np.meshgrid(
            np.linspace(cx - SURFACE_SPAN * sw, cx + SURFACE_SPAN * sw, 12),
            np.linspace(cy - SURFACE_SPAN * sd, cy + SURFACE_SPAN * sd, 12),
        )
        rays = np.zeros((gx.size, 6), dtype=np.float32)
        rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = gx.ravel(), gy.ravel(), 5.0, -1.0
        t = caster.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        tops = 5.0 - t[np.isfinite(t)]
        if len(tops) == 0:
            continue
        top = float(np.percentile(tops, SURFACE_QUANTILE))
        if top < OPEN_TO_FLOOR:  # an open bin or basket: the view reaches its bottom anyway
            continue
        ask = (z - SURFACE_MARGIN) / top
        fit[s.name] = {"top_fraction": round(top, 4), "height": round(ask, 4)}
        asks.append(ask)
    if not asks:
        return size[2], fit
    height = min(asks)
    if height < MIN_SQUASH * size[2]:
        raise ValueError(
            f"{type_name}: a model whose surface sits at {fit} of its height would be squashed "
            f"below {MIN_SQUASH:.0%} of the type's height; choose another model"
        )
    return height, fit


def fit_object(parts: list, size: tuple[float, float, float]) -> None:
    """Scale a model into the object's box, turned a quarter if its footprint lies across."""
    verts = np.concatenate([m.vertices for m, _ in parts])
    ext = verts.max(0) - verts.min(0)
    w, d, _ = size
    turn = (ext[0] > ext[1]) != (w > d) and max(ext[0], ext[1]) > 1.3 * min(ext[0], ext[1])
    for m, _ in parts:
        if turn:
            m.vertices = m.vertices[:, [1, 0, 2]] * [-1, 1, 1]
            m.vertex_normals = m.vertex_normals[:, [1, 0, 2]] * [-1, 1, 1]
    scale = np.asarray(size) / np.maximum(ext[[1, 0, 2]] if turn else ext, 1e-9)
    fit_into(parts, size)
    for m, _ in parts:
        n = m.vertex_normals / scale
        m.vertex_normals = n / np.linalg.norm(n, axis=1, keepdims=True).clip(1e-9)


def grout(image: Image.Image, tiles: int) -> Image.Image:
    """Tiles: ``tiles`` x ``tiles`` per image, with grey grout lines and a slight per-tile tone."""
    img = image.copy()
    draw = ImageDraw.Draw(img)
    w, h = img.size
    rng = np.random.default_rng(tiles)
    px = np.asarray(img, dtype=np.float32)
    for i in range(tiles):
        for j in range(tiles):
            x0, x1 = i * w // tiles, (i + 1) * w // tiles
            y0, y1 = j * h // tiles, (j + 1) * h // tiles
            px[y0:y1, x0:x1] *= 0.94 + 0.06 * rng.random()
    img = Image.fromarray(px.clip(0, 255).astype(np.uint8))
    draw = ImageDraw.Draw(img)
    line = max(1, w // 128)
    for i in range(tiles + 1):
        x = min(w - 1, i * w // tiles)
        draw.line([(x, 0), (x, h)], fill=(150, 150, 145), width=line)
        y = min(h - 1, i * h // tiles)
        draw.line([(0, y), (w, y)], fill=(150, 150, 145), width=line)
    return img


def write_manifest(out: Path, manifest: dict, merge: bool = False) -> Path:
    path = out / "manifest.json"
    if merge and path.exists():
        manifest = json.loads(path.read_text()) | manifest
    text = json.dumps(dict(sorted(manifest.items())), indent=1, sort_keys=True)
    path.write_text(text + "\n")
    return path


MODIFIED = {
    "furniture": "decimated, rescaled to the piece, textures downscaled, converted to glTF",
    "object": "decimated, rescaled to the object's size, textures downscaled, converted to glTF",
    "texture": "downscaled (tiles: grout lines drawn)",
}


def attribution(manifest: dict, notices: dict[str, str]) -> str:
    """ATTRIBUTION.md, from what the manifest says was read: for every source work its title,
    author, origin, licence with its URI, the file that states it, what was changed and where
    it is used; the licence texts that must travel with the work (``notices``: SPDX -> text)."""
    works: dict[tuple[str, str], dict] = {}
    for rel, entry in sorted(manifest.items()):
        for src in entry.get("sources", []):
            work = works.setdefault((src["source"], src["model"]), {"credit": src, "used": []})
            work["used"].append((rel, entry["kind"]))
    lines = [
        "# Attribution of the v2 assets",
        "",
        "Written by `maniskill-tidy derive-assets` from `manifest.json`, which holds what the",
        "derivation read from each source's own files; do not edit by hand. Every file under",
        "`data/` is a derived work of the sources listed here; each names what was changed.",
        "",
    ]
    for label in sorted({label for label, _ in works}):
        entries = sorted((model, w) for (lab, model), w in works.items() if lab == label)
        licences = sorted({w["credit"]["licence"] for _, w in entries})
        lines += [f"## {label} ({', '.join(licences)})", ""]
        for model, w in entries:
            c, used = w["credit"], w["used"]
            spdx = c["licence"]
            kinds = sorted({kind for _, kind in used})
            changed = "; ".join(MODIFIED[k] for k in kinds if k in MODIFIED)
            holder = c.get("holder") if c.get("holder") != c.get("author") else None
            lines += [
                f'- **"{c.get("title", model)}"** by {c.get("author", "unknown")}'
                + (f" (rights: {holder})" if holder else ""),
                f"  - source: `{model}`" + (f", <{c['url']}>" if c.get("url") else ""),
                f"  - licence: {NAMES[spdx]} ({spdx}), <{URIS[spdx]}>, as stated in "
                f"`{c['licence_file']}`",
            ]
            if changed and c["source"] != "maniskill-tidy":
                lines.append(f"  - modified: {changed}")
            lines.append(f"  - used in: {', '.join(rel for rel, _ in used)}")
        lines.append("")
    for spdx, text in sorted(notices.items()):
        lines += [f"## The {NAMES[spdx]} text", "", "```", text.strip(), "```", ""]
    return "\n".join(lines)
