"""Reading the offline sources: Sweet Home 3D furniture archives (.sh3f zips) and wheels.

An ``.sh3f`` is a zip holding ``PluginFurnitureCatalog.properties`` (name, size in cm, the
elevation objects rest at, an optional rotation, creator, per model) and one folder per model
with its OBJ, MTL, textures and, for Blend Swap models, a licence file naming title and author.
"""

from __future__ import annotations

import re
import tempfile
import zipfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

_ENTRY = re.compile(r"^(\w+)#(\d+)=(.*)$")
_BLEND = re.compile(r'Thank you for downloading "(.*)" by (.*)$')
_URL = re.compile(r"Downloaded from (https?://\S+)")


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

    def credit(self, model: CatalogModel) -> dict[str, str]:
        """Title, author and origin from the model's Blend Swap licence file, if it has one."""
        folder = str(Path(model.path).parent) + "/"
        for name in self.zip.namelist():
            if name.startswith(folder) and "LICENSE" in name.upper():
                text = self.zip.read(name).decode("latin-1")
                out = {}
                for line in text.splitlines():
                    if m := _BLEND.search(line):
                        out["title"], out["author"] = m.group(1).strip(), m.group(2).strip()
                    if m := _URL.search(line):
                        out["origin"] = m.group(1)
                return out
        return {}


class WheelFiles:
    """Files inside a wheel (a zip), extracted on demand."""

    def __init__(self, path: Path) -> None:
        if not path.is_file():
            raise FileNotFoundError(
                f"{path}: no such wheel; expected robosuite-1.5.2-py3-none-any.whl "
                "(`pip download --no-deps robosuite==1.5.2`)"
            )
        self.zip = zipfile.ZipFile(path)
        self.tmp = Path(tempfile.mkdtemp(prefix="wheel-"))

    def file(self, inner: str) -> Path:
        target = self.tmp / inner
        if not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(self.zip.read(inner))
        return target
