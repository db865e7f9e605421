"""CmprComm.: the map embedding goes through the sender's encoder (400 -> 100) and the
receiver's decoder (100 -> 400), trained with a reconstruction loss besides Eq. 2."""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812
from torch import nn

from maniskill_tidy.models.communication.base import MAP, STATE, Messenger, state_message

COMPRESSED = 100  # the code's length


class Compressed(Messenger):
    name = "cmpr"
    title = "CmprComm.: state and a 100-value code of the map embedding"
    label = "cmpr communication"

    def add_readers(self, cfg) -> int:
        self.encoder = nn.Linear(MAP, COMPRESSED)
        self.decoder = nn.Linear(COMPRESSED, MAP)
        return MAP

    def outgoing(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        state = state_message(x["va"], x["pose"], x["prev_task"])
        return torch.cat([state, self.encoder(self.map_embedding(x))], dim=-1)

    def incoming(self, m: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        state = self.state_reader(m[..., :STATE])
        decoded = self.decoder(m[..., STATE:])
        return self.read(torch.cat([state, decoded], dim=-1)), {"map": decoded}

    @classmethod
    def auxiliary_loss(cls, comms, x, extras, labels):
        """Reconstruct the sender's map embedding from its code."""
        sent = torch.stack([m.map_embedding(xn) for m, xn in zip(comms, x, strict=True)], -2)
        total = torch.zeros(())
        for pair in extras["pairs"]:
            ok = pair["received"]
            if ok.any():
                total = total + F.mse_loss(pair["map"][ok], sent.detach()[ok])
        return total
