"""HanGrCom, the paper's scheme, as a registered scheme: the mechanism (generators,
attention, the soft and the handshake modes) is ``models/hangrcom.py``; evaluation runs it
through ``policies/handshake_exchange.py`` in three rounds per step."""

from __future__ import annotations

import torch

from maniskill_tidy.models import hangrcom
from maniskill_tidy.models.communication.base import Scheme


class HanGrComScheme(hangrcom.HanGrCom, Scheme):
    name = "hangrcom"
    title = "HanGrCom (paper Sections 5.3-5.5)"
    label = "HanGrCom"
    rounds = 3  # request, key, value
    protocol = "handshake"

    @classmethod
    def build(cls, cfg) -> HanGrComScheme:
        return cls(cfg.state, cfg.key, cfg.value, cfg.inter)

    @classmethod
    def communicate(cls, cfg, comms, sf, x, present, hard, labels, central):
        gens = [c(s) for c, s in zip(comms, sf, strict=True)]
        stack = {k: torch.stack([g[k] for g in gens], dim=2) for k in gens[0]}
        t = hangrcom.attention(stack["qry"], stack["key"], present)
        if hard:
            inn, inter = hangrcom.hard(t, stack["val"], stack["inv"], present, cfg.mu, cfg.delta)
        else:
            inn, inter = hangrcom.soft(t, stack["val"], stack["inv"])
        return inn, inter, {"T": t, "aux": torch.zeros(())}
