"""SAPIEN's BRDF lookup table, computed once per machine instead of once per process.

SAPIEN's camera shaders weight the environment map's light by a 512 x 512 BRDF table (the
split-sum approximation of image-based lighting). svulkan2 computes it with a compute shader at
a process's first picture: 5-6 s on lavapipe, 2 cores, about half of making an env
(``docs/research/probes/startup_probe.py``). The table depends on SAPIEN's shader and the
Vulkan driver alone, so it is read back once, through a camera whose shader copies its texels out
(``shaders/brdf_lut``), kept in the user's cache, and lent to every camera. The cameras then
sample the same texels with the same sampler (linear, clamped to the edge, no mipmaps) and draw
the same pixels, in both looks (``tests/test_brdf_lut.py`` compares them with SAPIEN's own
table). GPU rendering computes the table in milliseconds and keeps its own.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import sapien

from maniskill_tidy.sim import SHADERS, render_cache

SIZE = 512  # svulkan2's table, whatever size is asked for (SVResourceManager::generateBRDFLUT)


def cache_file() -> Path:
    key = hashlib.sha256(render_cache.driver().encode()).hexdigest()[:16]
    return render_cache.cache_dir() / f"brdf-lut-{key}.npy"


def read_back() -> np.ndarray:
    """SAPIEN's own table (SIZE, SIZE, 2) float16, as its cameras sample it: one picture of a
    wall through ``shaders/brdf_lut`` (the table's texels are half floats, exact in the float
    picture; ManiSkill makes "Color" 8-bit, so the shader writes a picture of its own)."""
    sapien.render.set_picture_format("Lut", "r32g32b32a32sfloat")
    scene = sapien.Scene()
    wall = scene.create_actor_builder()
    wall.add_box_visual(half_size=[0.1, 50.0, 50.0])
    wall.build_static("wall")
    camera = sapien.render.RenderCameraComponent(SIZE, SIZE, str(SHADERS / "brdf_lut"))
    camera.set_perspective_parameters(0.1, 10.0, SIZE, SIZE, SIZE / 2, SIZE / 2, 0.0)
    holder = sapien.Entity()
    holder.add_component(camera)
    holder.set_pose(sapien.Pose([-3.0, 0.0, 0.0]))  # looking along +x at the wall
    scene.add_entity(holder)
    scene.update_render()
    camera.take_picture()
    picture = camera.get_picture("Lut")[..., :2]
    table = picture.astype(np.float16)
    if picture.dtype != np.float32 or not np.array_equal(table.astype(np.float32), picture):
        raise RuntimeError(f"the BRDF table read back is not half floats ({picture.dtype})")
    return table


@functools.cache
def table() -> np.ndarray:
    """The table from the cache, read back and cached on a miss (or a damaged file)."""
    path = cache_file()
    try:
        cached = np.load(path)
        if cached.shape == (SIZE, SIZE, 2) and cached.dtype == np.float16:
            return cached
    except (OSError, ValueError, EOFError):
        pass
    fresh = read_back()
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".npy", delete=False) as tmp:
        np.save(tmp, fresh)
    os.replace(tmp.name, path)  # atomic: two workers may write it at once
    return fresh


@functools.cache
def texture() -> sapien.render.RenderTexture:
    return sapien.render.RenderTexture(
        table(), 2, "R16G16Sfloat", filter_mode="linear", address_mode="edge"
    )


def lend(cameras: Iterable[sapien.render.RenderCameraComponent]) -> None:
    """Give ``cameras`` the cached table, so that SAPIEN never computes its own."""
    for camera in cameras:
        camera.set_texture("BRDFLUT", texture())
