"""Making many objects at once without the garbage collector walking the whole process."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cycle collector off inside, as it was after. Loading a dataset makes a few
    hundred thousand objects, and the collections those allocations trigger walk everything the
    process holds (torch, SAPIEN, ManiSkill): the 120-house dataset's train split took 0.43-0.47 s
    to load beside those libraries, 0.23-0.30 s with the collector paused
    (``docs/research/probes/load_probe.py``). What is made is kept (no garbage
    cycles to miss), and the collector runs as usual afterwards."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
