"""w/o Comm.: nothing is sent; ``inn`` and ``int`` are zero."""

from __future__ import annotations

import torch

from maniskill_tidy.models.communication.base import Scheme


class NoCommunication(Scheme):
    name = "none"
    title = "no communication (w/o Comm.)"
    label = "no communication"
    protocol = "none"

    @classmethod
    def build(cls, cfg) -> None:
        return None

    @classmethod
    def communicate(cls, cfg, comms, sf, x, present, hard, labels, central):
        zeros = torch.zeros(*present.shape, cfg.inter)
        return torch.zeros(*present.shape, cfg.value), zeros, {"T": None, "aux": torch.zeros(())}
