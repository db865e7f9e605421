"""CondComm.: BroadComm's message, sent only while the agent's misplaced-object detector finds
a misplaced object in view (``mis >= 0.5``)."""

from __future__ import annotations

import torch

from maniskill_tidy.models.communication.base import Messenger

MISPLACED = 0.5  # it sends while its detector's best probability is at least this


class Conditional(Messenger):
    name = "cond"
    title = "CondComm.: state and map embedding while a misplaced object is in view"
    label = "cond communication"

    def sends(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return x["mis"] >= MISPLACED
