"""Reading the offline sources: Sweet Home 3D furniture archives (.sh3f zips) and wheels.

An ``.sh3f`` is a zip holding ``PluginFurnitureCatalog.properties`` (name, size in cm, the
elevation objects rest at, an optional rotation, creator, per model) and one folder per model
with its OBJ, MTL, textures and, for Blend Swap models, a licence file naming title and author.
"""

from __future__ import annotations

import html
import re
import tempfile
import zipfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from maniskill_tidy.assets.licences import check, identify

_ENTRY = re.compile(r"^(\w+)#(\d+)=(.*)$")
_HEADER = re.compile(r"^(\w+)=(.*)$")
_BLEND_TXT = re.compile(r'Thank you for downloading "(.*)" by (.*)$', re.M)
# Blend Swap's licence pages, newer ("93285 - Title - Downloaded from Blend Swap") and older
# ("Title by author - 71094 - Creative Commons License")
_BLEND_HTML = re.compile(r"<title>\s*\d+\s*-\s*(.*?)\s*-\s*Downloaded from Blend Swap", re.S)
_BLEND_OLD = re.compile(r"<title>\s*(.*?) by (.*?) - \d+ - Creative Commons License", re.S)
_URL = re.compile(r"(https?://www\.blendswap\.com/blends/view/\d+)")
_COPYRIGHT = re.compile(r"\(C\)\s*Copyrights?\s*(?:[\d-]+\s+)?(.*)")


@dataclass(frozen=True)
class CatalogModel:
    """One model of an archive, as its catalog describes it (sizes in metres)."""

    archive: str
    stem: str
    path: str  # inside the zip
    name: str
    size: tuple[float, float, float]  # width (x), depth, height
    drop_on_top: float | None  # metres above the bottom where objects rest, if given
    rotation: np.ndarray  # 3x3, applied to the OBJ's coordinates first
    creator: str


class Sh3fArchive:
    """A furniture archive, read lazily from its zip."""

    def __init__(self, path: Path, label: str) -> None:
        if not path.is_file():
            raise FileNotFoundError(
                f"{path}: no such furniture archive; expected Debian's sweethome3d-furniture "
                "(`apt-get install sweethome3d-furniture`: /usr/share/sweethome3d/furniture)"
            )
        self.path, self.label = path, label
        self.zip = zipfile.ZipFile(path)

    @cached_property
    def models(self) -> dict[str, CatalogModel]:
        text = self.zip.read("PluginFurnitureCatalog.properties").decode("latin-1")
        entries: dict[int, dict[str, str]] = {}
        for line in text.splitlines():
            m = _ENTRY.match(line.strip())
            if m:
                entries.setdefault(int(m.group(2)), {})[m.group(1)] = m.group(3)
        out = {}
        for e in entries.values():
            path = e["model"].lstrip("/")
            stem = Path(path).stem
            rot = e.get("modelRotation")
            rotation = np.array([float(v) for v in rot.split()]).reshape(3, 3) if rot else np.eye(3)
            drop = e.get("dropOnTopElevation")
            out[stem] = CatalogModel(
                archive=self.label,
                stem=stem,
                path=path,
                name=e.get("name", stem),
                size=tuple(float(e[k]) / 100 for k in ("width", "depth", "height")),
                drop_on_top=float(drop) / 100 if drop else None,
                rotation=rotation,
                creator=e.get("creator", ""),
            )
        return out

    def model(self, stem: str) -> CatalogModel:
        if stem not in self.models:
            raise KeyError(f"{self.label} has no model {stem!r}")
        return self.models[stem]

    def extract(self, model: CatalogModel, into: Path) -> Path:
        """Unpack a model's folder; returns the OBJ's path."""
        folder = str(Path(model.path).parent) + "/"
        for name in self.zip.namelist():
            if name.startswith(folder) and not name.endswith("/"):
                target = into / name
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(self.zip.read(name))
        return into / model.path

    @cached_property
    def header(self) -> dict[str, str]:
        """The catalog's own keys (``license``, ``provider``, ...), before its first model."""
        text = self.zip.read("PluginFurnitureCatalog.properties").decode("latin-1")
        return dict(m.groups() for m in map(_HEADER.match, text.splitlines()) if m)

    @cached_property
    def licence(self) -> tuple[str | None, str]:
        """The archive's licence as its ``LICENSE.TXT`` states it, and who holds the rights."""
        text = self.zip.read("LICENSE.TXT").decode("latin-1")
        return identify(text), text

    def holder(self, model: CatalogModel) -> str | None:
        """The copyright line of ``LICENSE.TXT`` that covers the model: the one whose list
        names it, or the one "for all the other models"; None if the text has none."""
        sections = re.split(r"\n(?=\s*\(C\))", self.licence[1])
        fallback = None
        for section in sections[1:] if len(sections) > 1 else []:
            m = _COPYRIGHT.search(section)
            if not m:
                continue
            listed = {line.strip()[2:].strip() for line in section.splitlines()
                      if line.strip().startswith("- ")}  # fmt: skip
            if model.stem in listed:
                return m.group(1).strip()
            if "all the other models" in section or not listed:
                fallback = m.group(1).strip()
        return fallback

    def model_licence_file(self, model: CatalogModel) -> tuple[str, str] | None:
        """(name, text) of the licence file in the model's own folder, if it has one."""
        folder = str(Path(model.path).parent) + "/"
        for name in sorted(self.zip.namelist()):
            if name.startswith(folder) and "LICENSE" in Path(name).name.upper():
                return name, self.zip.read(name).decode("utf-8", errors="replace")
        return None

    def credit(self, model: CatalogModel) -> dict[str, str]:
        """Title, author, origin and licence of a model, as the archive's files state them: the
        model's own licence file where it has one (Blend Swap's), else the archive's
        ``LICENSE.TXT`` and the catalog's entry. Raises if no file states a shippable licence."""
        what = f"{self.label}/{model.stem}"
        archive_spdx, _ = self.licence
        out = {"name": model.name, "title": model.name, "author": model.creator}
        own = self.model_licence_file(model)
        if own is None:
            spdx, where = archive_spdx, f"{self.path.name}:LICENSE.TXT"
            provider = self.header.get("provider", "")
            out["url"] = provider if "://" in provider or not provider else f"http://{provider}/"
        else:
            name, text = own
            spdx, where = identify(text), f"{self.path.name}:{name}"
            if m := _BLEND_TXT.search(text) or _BLEND_OLD.search(text):
                out["title"], out["author"] = (html.unescape(g).strip() for g in m.groups())
            elif m := _BLEND_HTML.search(text):
                out["title"] = html.unescape(m.group(1)).strip()
            if m := _URL.search(text):
                out["url"] = m.group(1)
            if spdx is not None and archive_spdx is not None and spdx != archive_spdx:
                raise ValueError(f"{what}: its licence file states {spdx}, its archive's "
                                 f"LICENSE.TXT {archive_spdx}; expected the same")  # fmt: skip
        out["licence"] = check(spdx, what, where)
        out["licence_file"] = where
        if holder := self.holder(model):
            out["holder"] = holder
        return out


class WheelFiles:
    """Files inside a wheel (a zip), extracted on demand."""

    def __init__(self, path: Path) -> None:
        if not path.is_file():
            raise FileNotFoundError(
                f"{path}: no such wheel; expected robosuite-1.5.2-py3-none-any.whl "
                "(`pip download --no-deps robosuite==1.5.2`)"
            )
        self.path = path
        self.zip = zipfile.ZipFile(path)
        self.tmp = Path(tempfile.mkdtemp(prefix="wheel-"))

    def file(self, inner: str) -> Path:
        target = self.tmp / inner
        if not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(self.zip.read(inner))
        return target

    @cached_property
    def dist_info(self) -> str:
        names = [n.split("/")[0] for n in self.zip.namelist() if n.endswith(".dist-info/METADATA")]
        if len(names) != 1:
            raise ValueError(f"{self.path}: expected one .dist-info/METADATA in the wheel")
        return names[0]

    def credit(self) -> dict[str, str]:
        """The project's licence as the wheel's own licence file states it, its copyright
        holders and home page (the wheel's METADATA). Raises if the licence is not shippable."""
        info = self.dist_info
        files = [n for n in self.zip.namelist()
                 if n.startswith(info) and Path(n).name.upper().startswith("LICEN")]  # fmt: skip
        if not files:
            raise ValueError(f"{self.path.name}: the wheel holds no licence file")
        text = self.zip.read(files[0]).decode("utf-8", errors="replace")
        meta = self.zip.read(f"{info}/METADATA").decode("utf-8", errors="replace")
        out = {"licence": check(identify(text), self.path.name, files[0])}
        out["licence_file"] = f"{self.path.name}:{files[0]}"
        out["licence_text"] = text.strip()
        if m := re.search(r"^Copyright \(c\)\s*(?:[\d-]+\s+)?(.*)$", text, re.M | re.I):
            out["holder"] = m.group(1).strip()
        if m := re.search(r"^Home-page:\s*(\S+)", meta, re.M):
            out["url"] = m.group(1)
        return out
