"""The object-memory team's sub-task head: a pointer over the jobs an agent could take next.

Each candidate (``policies/memory_candidates.py``: fetch a remembered object, check a report,
put down on a surface, explore, inspect, park) is embedded from its kind, its object type (the
type's word vector and a learned embedding), its receptacle type and its numbers, shifted by
the agent's context; one self-attention layer lets every candidate see the others (what is
nearest is a property of the set), and a linear layer scores each. The softmax over the scores
is the choice; padded slots (kind -1) never win. It runs when the agent needs a new job, not
every step (``bench --only teams`` times the team).
"""

from __future__ import annotations

import torch
from torch import nn


class MemoryPointer(nn.Module):
    def __init__(
        self, type_vectors: torch.Tensor, kinds: int, receptacles: int, numeric: int,
        context: int, dim: int = 64, heads: int = 4,
    ) -> None:  # fmt: skip
        super().__init__()
        self.numeric = numeric  # numbers per candidate row (memory_candidates.numeric_width)
        none = torch.zeros(1, type_vectors.shape[1])  # the last type: the candidate has none
        self.register_buffer("type_vectors", torch.cat([type_vectors.float(), none]))
        self.type_embedding = nn.Embedding(len(type_vectors) + 1, 16)
        self.kind = nn.Embedding(kinds, 16)
        self.rest = nn.Embedding(receptacles + 1, 16)  # the last: no receptacle type
        width = type_vectors.shape[1] + 16 * 3 + numeric
        self.entry = nn.Sequential(nn.Linear(width, dim), nn.ReLU(), nn.Linear(dim, dim))
        self.context = nn.Linear(context, dim)
        self.mix = nn.TransformerEncoderLayer(dim, heads, 2 * dim, dropout=0.0, batch_first=True)
        self.score = nn.Linear(dim, 1)

    def forward(
        self, kind: torch.Tensor, types: torch.Tensor, rest: torch.Tensor,
        numeric: torch.Tensor, context: torch.Tensor,
    ) -> torch.Tensor:  # fmt: skip
        """Logits (B, N) over the candidates (B, N); -inf where kind is -1."""
        h, present = self.encode(kind, types, rest, numeric, context)
        return self.score(h).squeeze(-1).masked_fill(~present, -torch.inf)

    def encode(
        self, kind: torch.Tensor, types: torch.Tensor, rest: torch.Tensor,
        numeric: torch.Tensor, context: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
        """Each candidate's features after attending to the others (B, N, dim), and which
        slots hold a candidate (B, N)."""
        kind, types, rest = kind.long(), types.long(), rest.long()
        present = kind >= 0
        x = torch.cat(
            [self.type_vectors[types], self.type_embedding(types), self.kind(kind.clamp(min=0)),
             self.rest(rest), numeric.float()], dim=-1,
        )  # fmt: skip
        h = self.entry(x) + self.context(context.float())[:, None]
        return self.mix(h, src_key_padding_mask=~present), present


class KindBias(nn.Module):
    """A pointer whose score of each candidate is raised by its kind's bias: a whole-policy
    change of a few numbers, for comparing policies on the same episodes
    (``docs/research/probes/kind_bias_probe.py``)."""

    def __init__(self, pointer: MemoryPointer, bias: list[float]) -> None:
        super().__init__()
        self.pointer, self.numeric = pointer, pointer.numeric
        self.register_buffer("bias", torch.tensor(bias, dtype=torch.float32))

    def forward(
        self, kind: torch.Tensor, types: torch.Tensor, rest: torch.Tensor,
        numeric: torch.Tensor, context: torch.Tensor,
    ) -> torch.Tensor:  # fmt: skip
        scores = self.pointer(kind, types, rest, numeric, context)
        return scores + self.bias[kind.long().clamp(min=0)]
