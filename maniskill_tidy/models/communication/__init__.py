"""The communication schemes of the paper (Section 6.3, Fig. 6), one module each, registered
by name (an agent config's ``model: communication: NAME``).

Every scheme gives an agent's F_a the same two inputs as HanGrCom, ``inn`` (value dims) and
``int`` (inter dims), so that a variant differs from the paper's model in its communication
only. What crosses between agents at evaluation is built by the same modules training runs.

Adding a scheme: a module with a :class:`~maniskill_tidy.models.communication.base.Scheme`
subclass (a :class:`~maniskill_tidy.models.communication.base.Messenger` for message passing),
a line in ``SCHEMES`` and an agent config.
"""

from __future__ import annotations

from maniskill_tidy.models.communication.base import MAP, STATE, TASK, Scheme
from maniskill_tidy.models.communication.broadcast import Broadcast
from maniskill_tidy.models.communication.central import Central
from maniskill_tidy.models.communication.cmpr import Compressed
from maniskill_tidy.models.communication.cond import Conditional
from maniskill_tidy.models.communication.hangrcom import HanGrComScheme
from maniskill_tidy.models.communication.inten import Intention
from maniskill_tidy.models.communication.none import NoCommunication

SCHEMES: dict[str, type[Scheme]] = {
    s.name: s
    for s in (
        HanGrComScheme, NoCommunication, Broadcast, Conditional, Compressed, Intention, Central,
    )
}  # fmt: skip


def scheme(name: str) -> type[Scheme]:
    """The scheme registered as ``name``."""
    if name not in SCHEMES:
        raise ValueError(f"unknown communication {name!r}; expected one of {list(SCHEMES)}")
    return SCHEMES[name]


__all__ = ["MAP", "SCHEMES", "STATE", "TASK", "Scheme", "scheme"]
