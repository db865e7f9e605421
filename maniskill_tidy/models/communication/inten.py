"""IntenComm.: only the state (10), which holds the sender's sub-task; the receiver predicts
the sender's next sub-goal (dx, dy) with a learned head, trained on the sender's labels, and
reads the message together with that intention."""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812
from torch import nn

from maniskill_tidy.models.communication.base import STATE, Messenger, state_message

OFFSETS = 9  # dx and dy: -4 .. 4 cells


class Intention(Messenger):
    name = "inten"
    title = "IntenComm.: state and sub-task, and the teammates' predicted sub-goals"
    label = "inten communication"
    sends_map = False

    def add_readers(self, cfg) -> int:
        self.intent = nn.Linear(64, 2 * OFFSETS)  # the sender's next dx and dy
        return 2 * OFFSETS

    def outgoing(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return state_message(x["va"], x["pose"], x["prev_task"])

    def incoming(self, m: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        state = self.state_reader(m[..., :STATE])
        intent = self.intent(state)
        parts = [state, intent[..., :OFFSETS].softmax(-1), intent[..., OFFSETS:].softmax(-1)]
        return self.read(torch.cat(parts, dim=-1)), {"intent": intent}

    @classmethod
    def auxiliary_loss(cls, comms, x, extras, labels):
        """Predict the sender's sub-goal (dx, dy) labels."""
        total = torch.zeros(())
        if labels is None:
            return total
        for pair in extras["pairs"]:
            ok = pair["received"]
            if not ok.any():
                continue
            for k, head in enumerate(("dx", "dy")):
                y = torch.stack([yj[head] for yj in labels], dim=-1)  # (…, N) sender labels
                logits = pair["intent"][..., OFFSETS * k : OFFSETS * (k + 1)]
                mask = ok & (y >= 0)
                if mask.any():
                    total = total + F.cross_entropy(logits[mask], y[mask])
        return total
