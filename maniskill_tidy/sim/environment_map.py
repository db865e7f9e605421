"""v2's environment map, prefiltered once per machine instead of once per process.

SAPIEN turns the environment map (``assets/data/environment.hdr``, a 256 x 128 lat-long image
that stb reads as 8-bit) into a cube map and prefilters its mip levels for rough reflections with
a compute shader, at a process's first picture: about 2 s on lavapipe, 2 cores, a quarter of
making a v2 env (``docs/research/probes/startup_probe.py``). The result depends on the image,
SAPIEN's shader and the Vulkan driver alone, so it is exported once with every level (SAPIEN's
``RenderCubemap.export``, a KTX file), kept in the user's cache beside the BRDF table
(``brdf_lut.py``), and loaded from there: svulkan2 takes a KTX file's mip levels as they are and
prefilters nothing, and the cameras draw the same pixels (``tests/test_environment_map.py``).
GPU rendering prefilters in milliseconds, but reads the same file.
"""

from __future__ import annotations

import functools
import hashlib
import os
import struct
import tempfile
from pathlib import Path

import sapien

from maniskill_tidy import assets
from maniskill_tidy.sim import render_cache

SOURCE = "environment.hdr"
LEVELS = 5  # the mip levels SAPIEN's RenderCubemap(filename) asks for
KTX2 = b"\xabKTX 20\xbb\r\n\x1a\n"
R8G8B8A8_UNORM = 37  # VkFormat: the only one svulkan2 loads from a KTX file


def cache_file(source: Path) -> Path:
    """Keyed by the image's bytes and the driver (another driver may prefilter other bits)."""
    digest = hashlib.sha256(render_cache.driver().encode())
    digest.update(source.read_bytes())
    return render_cache.cache_dir() / f"environment-{digest.hexdigest()[:16]}.ktx"


def complete(path: Path) -> bool:
    """Whether ``path`` is a KTX2 cube map of :data:`LEVELS` 8-bit levels, every level's bytes
    present: svulkan2 would read a damaged file without a word, or crash on it."""
    try:
        data = path.read_bytes()
    except OSError:
        return False
    if len(data) < 80 + 24 * LEVELS or not data.startswith(KTX2):
        return False
    vk_format, *_, faces, levels = struct.unpack_from("<8I", data, 12)
    if (vk_format, faces, levels) != (R8G8B8A8_UNORM, 6, LEVELS):
        return False
    index = [struct.unpack_from("<3Q", data, 80 + 24 * i) for i in range(LEVELS)]
    return all(0 < length and offset + length <= len(data) for offset, length, _ in index)


@functools.cache
def cubemap() -> sapien.render.RenderCubemap:
    """The prefiltered cube map from the cache; made and exported on a miss (or a damaged file)."""
    source = assets.path(SOURCE)
    path = cache_file(source)
    if complete(path):
        return sapien.render.RenderCubemap(str(path))
    fresh = sapien.render.RenderCubemap(str(source))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".ktx", delete=False) as tmp:
            pass
    except OSError:  # no cache to write to: this process prefilters for itself
        return fresh
    try:
        fresh.export(tmp.name)  # uploads, and so prefilters, the fresh map first
        os.replace(tmp.name, path)  # atomic: two workers may write it at once
    finally:
        Path(tmp.name).unlink(missing_ok=True)
    return fresh
