"""sq and the commonsense attentions of the receptacle predictor.

``KnowledgeGCN``: two graph-convolution layers (torch_geometric's ``GCNConv``) over the
commonsense graph give sq, one embedding per type node. The paper also joins the visual
embedding to every node's features; here the graph runs once per batch on the word vectors
and sv joins the detector and predictor directly.

``CommonsenseAttention``: scaled dot-product attention of a query (sl for the
object-commonsense attention attl, sr for the room-commonsense attention attr) over sq, added
to the query (a residual), so that the model without knowledge is the same model with the
attention term removed.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch_geometric.nn import GCNConv

from maniskill_tidy.models.knowledge_graph import KnowledgeGraph


class KnowledgeGCN(nn.Module):
    def __init__(self, graph: KnowledgeGraph, dim: int = 256) -> None:
        super().__init__()
        self.register_buffer("features", graph.features.float())
        self.register_buffer("edge_index", graph.edge_index)
        self.register_buffer("edge_weight", graph.edge_weight)
        self.conv1 = GCNConv(graph.features.shape[1], dim)
        self.conv2 = GCNConv(dim, dim)

    def forward(self) -> torch.Tensor:
        """sq: (nodes, dim)."""
        x = torch.relu(self.conv1(self.features, self.edge_index, self.edge_weight))
        return self.conv2(x, self.edge_index, self.edge_weight)


class CommonsenseAttention(nn.Module):
    def __init__(self, dim: int = 256) -> None:
        super().__init__()
        self.q, self.k, self.v = nn.Linear(dim, dim), nn.Linear(dim, dim), nn.Linear(dim, dim)
        self.norm = nn.LayerNorm(dim)

    def forward(self, query: torch.Tensor, sq: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(attended feature (B, dim), attention weights over the nodes (B, nodes))."""
        return self.attend(query, *self.keys_values(sq))

    def keys_values(self, sq: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The nodes' keys and values: they depend on the weights alone, so a frozen model
        may compute them once (``PerceptionModel.frozen``)."""
        return self.k(sq), self.v(sq)

    def attend(
        self, query: torch.Tensor, keys: torch.Tensor, values: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        scores = self.q(query) @ keys.T / math.sqrt(query.shape[-1])
        weights = scores.softmax(dim=-1)
        return self.norm(query + weights @ values), weights
