"""BroadComm.: every agent sends its state (10) and a map embedding (400, a learned projection
of its map feature ``sm``) to every teammate; ``inn`` is the mean of what it reads of the
messages, ``int`` their element-wise max."""

from __future__ import annotations

from maniskill_tidy.models.communication.base import Messenger


class Broadcast(Messenger):
    name = "broadcast"
    title = "BroadComm.: state and map embedding to every teammate"
    label = "broadcast communication"
