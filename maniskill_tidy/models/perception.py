"""The perception and reasoning half of the paper's model (Section 5.1-5.2), one class.

``PerceptionModel(knowledge=True)`` is the paper's; ``knowledge=False`` is its "w/o Know."
ablation: the same modules with the commonsense attentions removed (attl = sl, attr = sr).

Data flow for one detected object seen in one frame:

    rgb ──VisualEncoder──▶ sv ─┬──────────────────────────────┐
    seen types ──RoomClassifier(·, sv)──▶ sr ──attention(sq)──▶ attr ─┤
    detection ──DetectionEncoder──▶ sl ──attention(sq)──▶ attl ───────┤
    word vectors ──KnowledgeGCN──▶ sq                                 ▼
                                 [attl, attr, sv] ──▶ F_d (det, fd), F_p (p, r, fp)
    map crop ──SceneEncoder──▶ sm    (used by the decision modules of the next issue)
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from maniskill_tidy.models import scene_encoder, visual_encoder
from maniskill_tidy.models.commonsense import CommonsenseAttention, KnowledgeGCN
from maniskill_tidy.models.detection_encoder import DetectionEncoder
from maniskill_tidy.models.knowledge_graph import KnowledgeGraph
from maniskill_tidy.models.misplaced_detector import MisplacedDetector
from maniskill_tidy.models.receptacle_predictor import ReceptaclePredictor
from maniskill_tidy.models.room_classifier import RoomClassifier
from maniskill_tidy.models.scene_encoder import RegionQueries, SceneEncoder
from maniskill_tidy.models.visual_encoder import VisualEncoder


@dataclass(frozen=True)
class PerceptionConfig:
    categories: int  # K: the catalog's categories (map channels are K + 2)
    receptacles: int  # P: the catalog's receptacle types
    regions: int = 4  # scene-encoder queries per category (2 x 2 sub-regions)
    crop: int = 20  # G
    dim: int = 256
    knowledge: bool = True
    # the encoders' channels; the shipped models use the defaults, cheaper ones fewer
    # (``train perception --visual-widths --scene-widths``, issue 48)
    visual_widths: tuple[int, ...] = visual_encoder.WIDTHS
    scene_widths: tuple[int, ...] = scene_encoder.WIDTHS

    def __post_init__(self) -> None:  # a config read back from JSON holds lists
        object.__setattr__(self, "visual_widths", tuple(self.visual_widths))
        object.__setattr__(self, "scene_widths", tuple(self.scene_widths))


@dataclass
class Reasoning:
    """The outputs for a batch of detections."""

    det: torch.Tensor  # (B, 2) logits [reasonable, misplaced]
    receptacle: torch.Tensor  # (B, P) multi-label logits
    room: torch.Tensor  # (B, 4) multi-label logits
    fd: torch.Tensor  # (B, dim) F_d's second-to-last layer
    fp: torch.Tensor  # (B, dim) F_p's second-to-last layer
    attention: torch.Tensor | None  # (B, nodes): attl's weights over the graph


class PerceptionModel(nn.Module):
    def __init__(
        self, cfg: PerceptionConfig, type_vectors: torch.Tensor, graph: KnowledgeGraph
    ) -> None:
        super().__init__()
        self.cfg = cfg
        d = cfg.dim
        self.visual = VisualEncoder(d, cfg.visual_widths)
        self.visible = nn.Linear(d, cfg.categories)  # the visual encoder's pre-training head
        self.scene = SceneEncoder(cfg.categories + 2, cfg.crop, d, cfg.scene_widths)
        self.queries = RegionQueries(cfg.regions, cfg.categories, d)
        self.room_classifier = RoomClassifier(cfg.categories, d)
        self.detection = DetectionEncoder(type_vectors, cfg.receptacles, dim=d)
        # The graph is kept in both variants (its nodes name the attention weights); only
        # the model with knowledge reads it.
        self.gcn = KnowledgeGCN(graph, d)
        self.nodes = graph.nodes
        if cfg.knowledge:
            self.object_attention = CommonsenseAttention(d)
            self.room_attention = CommonsenseAttention(d)
        self.detector = MisplacedDetector(3 * d, d)
        self.predictor = ReceptaclePredictor(3 * d, cfg.receptacles, d)

    # The stages of Eq. 1, each usable on its own (the trainer freezes earlier stages).
    def sv(self, rgb: torch.Tensor) -> torch.Tensor:
        return self.visual(rgb)

    def sm(self, crop: torch.Tensor) -> torch.Tensor:
        return self.scene(crop)

    def sr(self, seen: torch.Tensor, sv: torch.Tensor) -> torch.Tensor:
        return self.room_classifier.embed(seen, sv)

    def frozen(self, name: str, modules: list[nn.Module], compute):
        """``compute()``, which depends on the weights of ``modules`` alone: a frozen model
        (eval mode, no gradient) computes it once and reuses it until one of those weights
        changes (a learned team asks for it on every step of every agent)."""
        if self.training or torch.is_grad_enabled():
            return compute()
        # parameters and buffers, not state_dict: this runs per step
        tensors = [t for m in modules for t in (*m.parameters(), *m.buffers())]
        key = tuple((t.data_ptr(), t._version) for t in tensors)
        cache = self.__dict__.setdefault("_frozen", {})
        if cache.get(name, (None,))[0] != key:
            cache[name] = (key, compute())
        return cache[name][1]

    def knowledge_nodes(self) -> torch.Tensor:
        """sq (frozen: once)."""
        return self.frozen("sq", [self.gcn], self.gcn)

    def _commonsense(self, name: str, query: torch.Tensor):
        """attl or attr and its weights; the nodes' keys and values once while frozen."""
        attention = getattr(self, name)
        keys_values = self.frozen(
            name, [self.gcn, attention], lambda: attention.keys_values(self.knowledge_nodes())
        )
        return attention.attend(query, *keys_values)

    def reason(
        self,
        sv: torch.Tensor,
        sr: torch.Tensor,
        kind: torch.Tensor,
        rest: torch.Tensor,
        numeric: torch.Tensor,
    ) -> Reasoning:
        """F_d and F_p for detections, given their frames' (frozen) sv and sr."""
        sl = self.detection(kind, rest, numeric)
        weights = None
        if self.cfg.knowledge:
            attl, weights = self._commonsense("object_attention", sl)
            attr, _ = self._commonsense("room_attention", sr)
        else:
            attl, attr = sl, sr
        x = torch.cat([attl, attr, sv], dim=-1)
        fd = self.detector.features(x)
        fp = self.predictor.features(x)
        return Reasoning(
            self.detector.head(fd),
            self.predictor.receptacle(fp),
            self.predictor.room(fp),
            fd,
            fp,
            weights,
        )

    @torch.no_grad()
    def step_features(
        self,
        rgb: torch.Tensor,
        seen: torch.Tensor,
        crop: torch.Tensor,
        det_row: torch.Tensor,
        det_type: torch.Tensor,
        det_rest: torch.Tensor,
        det_numeric: torch.Tensor,
    ) -> dict[str, torch.Tensor]:
        """What the decision modules read of B frames (frozen): sv, sm, and fd, fp of the
        detection the detector finds most likely misplaced (zeros without one), its
        probability ``mis`` and whether there was a detection (``det``); ``p_detections``
        holds every detection's probability of being misplaced, ``p_receptacles`` (D, P) the
        reasonable-receptacle predictor's probability of each receptacle type for it.

        ``rgb`` (B, 64, 64, 3) uint8, ``seen`` (B, K), ``crop`` (B, G, G, K + 2) 0/1; the
        detections are flat, ``det_row`` naming each one's frame."""
        sv = self.sv(rgb)
        out = {"sv": sv, "sm": self.sm(crop)}
        b, d = len(sv), self.cfg.dim
        fd, fp = torch.zeros(b, d), torch.zeros(b, d)
        mis, det, p = torch.zeros(b), torch.zeros(b), torch.zeros(len(det_row))
        receptacles = torch.zeros(len(det_row), self.cfg.receptacles)
        if len(det_row):
            sr = self.sr(seen[det_row], sv[det_row])
            r = self.reason(sv[det_row], sr, det_type, det_rest, det_numeric)
            p = torch.softmax(r.det, -1)[:, 1]
            best = torch.full((b,), -1.0).scatter_reduce(0, det_row, p, "amax")
            # the first detection of each frame that reaches its frame's best probability
            first = torch.full((b,), len(p)).scatter_reduce(
                0, det_row, torch.where(p == best[det_row], torch.arange(len(p)), len(p)), "amin"
            )
            has = first < len(p)
            fd[has], fp[has] = r.fd[first[has]], r.fp[first[has]]
            mis[has], det[has] = p[first[has]], 1.0
            receptacles = torch.sigmoid(r.receptacle)
        out.update(fd=fd, fp=fp, mis=mis, det=det, p_detections=p, p_receptacles=receptacles)
        return out
