"""The hierarchical decision of the paper (Sections 5.3-5.4, Table 2): per agent, F_s -> HanGrCom
-> F_a (sub-task) -> F_g (sub-goal). One :class:`AgentDecision` per agent of the team:
heterogeneous agents do not share weights.

Per agent and step, from the frozen perception features (``PerceptionModel.step_features``)::

    (va, pose, held, failed, fd, fp, mis) ──F_s (linear + LSTM)──▶ sf
    sf ──HanGrCom generators──▶ qry, key, val, inv      (exchanged: see models/hangrcom.py)
    (sf, inn, int) ──F_a: LSTM → Linear(·, 256) = se → heads──▶ Explore/Place, o, p, r
    (se, sm, sp, sv[, sl]) ──F_g: LSTM → Linear(·, 256) → heads──▶ dx 9, dy 9, drot 4, ope 4, stop 2

Sizes: the paper's LSTMs have 512 hidden units; here ``hidden`` (128 by default) keeps the
shipped fp16 checkpoints a few MB per agent; the structure is the paper's. F_s's input adds to
the paper's (va, pose, fd, fp) the held object's type, whether the agent's own last action
failed, and the detector's probability for the chosen detection: all of it the agent's own.
With ``layout`` F_g also reads ``sl``, the map crop's geometry (obstacles, explored cells, any
object) through a small CNN trained with it: the frozen ``sm`` was trained to say which
categories the map holds, not where the unexplored space is, and a sub-goal is a direction.
With ``goal_map`` (needs ``layout``) that CNN reads a fourth channel, the sub-task's target in
the crop: the crop's pickupable-type channels weighted by F_a's softmax over ``o`` while the
agent's hands are empty, its receptacle-type channels weighted by the softmax over ``p`` while it
holds something. This is how the sub-goal is conditioned on the sub-task here (hierarchical
decision); it is differentiable, so F_g's loss trains F_a's heads too. It is this project's
addition to the paper's F_g inputs (``sm`` alone did not place a target: docs/models.md,
"The learned team"). With ``wide_layout`` F_g also reads ``sw``, a second CNN of the same
shape over the agent's whole map at 1 m per cell (``crops.wide_layout``): the 5 m crop rarely
holds the frontier the exploring teacher walks to (on val it did not help: docs/models.md,
"The learned team").
With ``suspects`` F_s also reads, per pickupable type, the detector's highest probability that
a detection of that type is misplaced, in this frame and over the episode so far (a running
maximum kept as part of F_s's recurrent state): on val, F_a named the teacher's target type on
13 % of Place steps (the model card) though the agent had itself detected that type before on
82 % of them (``docs/research/probes/object_memory.py``), and ``fd`` carries one detection
per frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch
from torch import nn

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.models.communication import scheme
from maniskill_tidy.models.hangrcom import DELTA, MU
from maniskill_tidy.perception.map_grid import EXPLORED, FIRST_CHANNEL, OBSTACLE

POSE = 5  # x / 10 m, y / 10 m, cos and sin of the heading, camera pitch / 60 degrees
HEADS_TASK = ("kind", "object", "receptacle", "room")
HEADS_GOAL = ("dx", "dy", "drot", "ope", "stop")
LAYOUT = 3  # crop channels sl reads: obstacle, explored, any object


@lru_cache(maxsize=1)
def goal_channels() -> tuple[np.ndarray, np.ndarray]:
    """Crop channels of the catalog's pickupable types and receptacle types (-1: not mapped)."""
    catalog = load_catalog()
    index = {name: FIRST_CHANNEL + i for i, name in enumerate(catalog.categories)}
    obj = np.array([index.get(t, -1) for t in catalog.pickupable])
    rec = np.array([index.get(t, -1) for t in catalog.receptacles])
    return obj, rec


@dataclass(frozen=True)
class DecisionConfig:
    categories: int = 119  # K (held object types)
    objects: int = 62  # o: pickupable types
    receptacles: int = 46  # p
    rooms: int = 4  # r
    perception: int = 256  # sv, sm, fd, fp
    state: int = 128  # sf
    key: int = 32  # qry, key
    value: int = 64  # val
    inter: int = 64  # inv
    hidden: int = 128  # F_a and F_g LSTMs (the paper's 512, shrunk)
    embed: int = 256  # se and F_g's last hidden layer (Table 2)
    layout: bool = False  # F_g reads sl (the crop's geometry) too
    wide_layout: bool = False  # F_g reads sw (the whole map's coarse layout) too
    goal_map: bool = False  # sl also reads the sub-task's target in the crop (needs layout)
    suspects: bool = False  # F_s reads per-type misplaced probabilities, now and the episode's max
    communication: str = "hangrcom"  # a scheme registered in models/communication/
    # ablations (paper Section 6.5): without the misplaced-object detector F_s gets no fd and no
    # misplaced probability, without the reasonable-receptacle predictor no fp (zeros: the
    # layer sizes stay those of the full model)
    misplaced_detector: bool = True
    receptacle_predictor: bool = True
    # w/o HierDec.: no sub-task and sub-goal; one LSTM predicts the env's low-level action
    hierarchical: bool = True
    mu: float = MU
    delta: float = DELTA
    # A sub-goal step every k env steps (the paper's "at each sub-goal step", Section 5): the
    # agents run the perception model, F_s, HanGrCom and F_a / F_g only then, and pursue the
    # sub-goal in between; the LSTMs are trained on every k-th row of the demonstrations.
    # 1 (the shipped models): every env step is a sub-goal step.
    decide_every: int = 1


@lru_cache(maxsize=1)
def pickupable_index() -> np.ndarray:
    """Per catalog category (a detection's type), its index among the pickupable types (-1:
    not pickupable)."""
    catalog = load_catalog()
    where = {name: i for i, name in enumerate(catalog.pickupable)}
    return np.array([where.get(name, -1) for name in catalog.categories])


def suspects(det_row: torch.Tensor, det_type: torch.Tensor, p: torch.Tensor, frames: int,
             objects: int) -> torch.Tensor:  # fmt: skip
    """(frames, objects): per pickupable type, the highest probability ``p`` the detector gives
    a detection of that type in the frame of being misplaced (0: none of that type in view).
    Detections are flat, ``det_row`` naming each one's frame."""
    kind = torch.from_numpy(pickupable_index())[det_type.long()]
    keep = kind >= 0
    out = torch.zeros(frames * objects)
    out.scatter_reduce_(0, det_row[keep].long() * objects + kind[keep], p[keep].float(), "amax")
    return out.reshape(frames, objects)


def encode_pose(pose: torch.Tensor) -> torch.Tensor:
    """(…, 4) x, y, rotation, pitch -> (…, POSE)."""
    yaw = torch.deg2rad(pose[..., 2])
    return torch.stack(
        [pose[..., 0] / 10, pose[..., 1] / 10, torch.cos(yaw), torch.sin(yaw), pose[..., 3] / 60],
        dim=-1,
    )


def crop_layout(crop: np.ndarray) -> np.ndarray:
    """(…, G, G, K + 2) 0/1 crop (semantic_map channels: obstacle, explored, categories) ->
    (…, G, G, LAYOUT) uint8: obstacle, explored, any object."""
    crop = np.asarray(crop, dtype=bool)
    objects = crop[..., FIRST_CHANNEL:].any(-1)
    return np.stack([crop[..., OBSTACLE], crop[..., EXPLORED], objects], -1).astype(np.uint8)


def goal_maps(crop: np.ndarray) -> np.ndarray:
    """(…, G, G, K + 2) 0/1 crop -> (…, G, G, o + p) bool: its pickupable-type and
    receptacle-type channels (a type the map has no channel for stays empty)."""
    crop = np.asarray(crop, dtype=bool)
    obj, rec = goal_channels()
    picked = np.take(crop, np.concatenate([obj, rec]).clip(min=0), axis=-1)
    picked[..., np.concatenate([obj, rec]) < 0] = False
    return picked


def crop_goal(crop: np.ndarray) -> np.ndarray:
    """:func:`goal_maps`, bit-packed: (…, G * G * (o + p) / 8) uint8 (a few kB per training
    row instead of 43 kB)."""
    crop = np.asarray(crop)
    return np.packbits(goal_maps(crop).reshape(*crop.shape[:-3], -1), axis=-1)


def unpack_goal(packed: torch.Tensor, size: int, types: int) -> torch.Tensor:
    """Inverse of :func:`crop_goal`'s packing: (…, bytes) uint8 -> (…, G, G, types) float."""
    shifts = torch.arange(7, -1, -1, dtype=torch.uint8, device=packed.device)
    bits = (packed[..., None] >> shifts) & 1
    bits = bits.flatten(-2)[..., : size * size * types]
    return bits.reshape(*packed.shape[:-1], size, size, types).float()


class LayoutEncoder(nn.Module):
    """sl, sw: a small CNN over a map's geometry (20 x 20 x LAYOUT -> 64)."""

    def __init__(self, out: int = 64, channels: int = LAYOUT) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(channels, 16, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(4), nn.Flatten(), nn.Linear(32 * 16, out), nn.ReLU(),
        )  # fmt: skip

    def forward(self, layout: torch.Tensor) -> torch.Tensor:
        """(…, G, G, channels) in [0, 1] -> (…, out)."""
        lead = layout.shape[:-3]
        x = layout.reshape(-1, *layout.shape[-3:]).permute(0, 3, 1, 2).float()
        return self.net(x).reshape(*lead, -1)


class StateExtractor(nn.Module):
    """F_s: linear layers and an LSTM over the agent's own state and detector features."""

    def __init__(self, cfg: DecisionConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.held = nn.Embedding(cfg.categories + 1, 16)  # index 0: holds nothing
        width = 3 + POSE + 16 + 1 + 2 * cfg.perception + 2 + 2 * cfg.objects * cfg.suspects
        self.fuse = nn.Sequential(nn.Linear(width, cfg.state), nn.ReLU())
        self.lstm = nn.LSTM(cfg.state, cfg.state, batch_first=True)

    def forward(self, x: dict[str, torch.Tensor], state=None):
        """Inputs (B, T, ·) -> sf (B, T, state) and the recurrent state: the LSTM's, and with
        ``suspects`` the running maximum (B, objects) too."""
        lstm_state, memory = state if state is not None else (None, None)
        fd, fp, mis = x["fd"], x["fp"], x["mis"][..., None]
        if not self.cfg.misplaced_detector:
            fd, mis = torch.zeros_like(fd), torch.zeros_like(mis)
        if not self.cfg.receptacle_predictor:
            fp = torch.zeros_like(fp)
        parts = [x["va"], encode_pose(x["pose"]), self.held(x["held"] + 1),
                 x["failed"][..., None], fd, fp, mis, x["det"][..., None]]  # fmt: skip
        if self.cfg.suspects:
            now = x["suspect"].float() * self.cfg.misplaced_detector
            so_far = torch.cummax(now, dim=1).values
            if memory is not None:
                so_far = torch.maximum(so_far, memory[:, None])
            parts += [now, so_far]
            memory = so_far[:, -1]
        sf, lstm_state = self.lstm(self.fuse(torch.cat(parts, dim=-1)), lstm_state)
        return sf, (lstm_state, memory)


class SubTaskPredictor(nn.Module):
    """F_a: LSTM -> Linear(hidden, 256) = se -> Explore/Place, o, p, r."""

    def __init__(self, cfg: DecisionConfig, width: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(width, cfg.hidden, batch_first=True)
        self.embed = nn.Sequential(nn.Linear(cfg.hidden, cfg.embed), nn.ReLU())
        self.heads = nn.ModuleDict(
            {"kind": nn.Linear(cfg.embed, 2), "object": nn.Linear(cfg.embed, cfg.objects),
             "receptacle": nn.Linear(cfg.embed, cfg.receptacles),
             "room": nn.Linear(cfg.embed, cfg.rooms)}
        )  # fmt: skip

    def forward(self, x: torch.Tensor, state=None):
        h, state = self.lstm(x, state)
        se = self.embed(h)
        return se, {k: head(se) for k, head in self.heads.items()}, state


class SubGoalPredictor(nn.Module):
    """F_g: LSTM -> Linear(hidden, 256) -> dx 9, dy 9, drot 4, ope 4, stop 2."""

    def __init__(self, cfg: DecisionConfig) -> None:
        super().__init__()
        self.pose = nn.Sequential(nn.Linear(POSE, 32), nn.ReLU())  # sp
        if cfg.goal_map and not cfg.layout:
            raise ValueError("DecisionConfig.goal_map needs layout: true (the goal is its channel)")
        self.cfg = cfg
        channels = LAYOUT + (1 if cfg.goal_map else 0)
        self.layout = LayoutEncoder(channels=channels) if cfg.layout else None  # sl
        self.wide = LayoutEncoder() if cfg.wide_layout else None  # sw
        width = cfg.embed + 2 * cfg.perception + 32 + 64 * (cfg.layout + cfg.wide_layout)
        self.lstm = nn.LSTM(width, cfg.hidden, batch_first=True)
        self.hidden = nn.Sequential(nn.Linear(cfg.hidden, cfg.embed), nn.ReLU())
        self.heads = nn.ModuleDict(
            {"dx": nn.Linear(cfg.embed, 9), "dy": nn.Linear(cfg.embed, 9),
             "drot": nn.Linear(cfg.embed, 4), "ope": nn.Linear(cfg.embed, 4),
             "stop": nn.Linear(cfg.embed, 2)}
        )  # fmt: skip

    def forward(self, se, x: dict[str, torch.Tensor], state=None, task=None):
        parts = [se, x["sm"], self.pose(encode_pose(x["pose"])), x["sv"]]
        if self.layout is not None:
            layout = x["layout"].float()
            if self.cfg.goal_map:
                layout = torch.cat([layout, self.goal(x, task)[..., None]], dim=-1)
            parts.append(self.layout(layout))
        if self.wide is not None:
            parts.append(self.wide(x["wide"].float() / 255))
        h, state = self.lstm(torch.cat(parts, dim=-1), state)
        h = self.hidden(h)
        return {k: head(h) for k, head in self.heads.items()}, state

    def goal(self, x: dict[str, torch.Tensor], task: dict[str, torch.Tensor]) -> torch.Tensor:
        """(…, G, G) the sub-task's target in the crop: the object while the hands are empty,
        the receptacle while holding (probabilities of F_a's heads over the crop's channels)."""
        if "goal_maps" in x:  # an agent's own step: its crop's maps, never packed
            maps = x["goal_maps"]
        else:  # training rows store them bit-packed
            size = x["layout"].shape[-2]
            maps = unpack_goal(x["goal"], size, self.cfg.objects + self.cfg.receptacles)
        obj = torch.einsum("...hwk,...k->...hw", maps[..., : self.cfg.objects],
                           task["object"].softmax(-1))  # fmt: skip
        rec = torch.einsum("...hwk,...k->...hw", maps[..., self.cfg.objects :],
                           task["receptacle"].softmax(-1))  # fmt: skip
        holding = (x["held"] >= 0)[..., None, None]
        return torch.where(holding, rec, obj)


class DirectPolicy(nn.Module):
    """w/o HierDec. (paper Section 6.5): LSTM -> Linear(hidden, 256) -> the low-level action
    (the env's 11), trained on the teacher's actions. A receptacle-type head only names the
    surface a PutDown targets (the env's PutDown needs one), as a detector's output would."""

    def __init__(self, cfg: DecisionConfig, width: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(width, cfg.hidden, batch_first=True)
        self.embed = nn.Sequential(nn.Linear(cfg.hidden, cfg.embed), nn.ReLU())
        self.heads = nn.ModuleDict(
            {"action": nn.Linear(cfg.embed, len(Action)),
             "receptacle": nn.Linear(cfg.embed, cfg.receptacles)}
        )  # fmt: skip

    def forward(self, x: torch.Tensor, state=None):
        h, state = self.lstm(x, state)
        h = self.embed(h)
        return {k: head(h) for k, head in self.heads.items()}, state


class AgentDecision(nn.Module):
    """One agent's F_s, communication (HanGrCom's generators or a baseline's messenger), F_a
    and F_g."""

    def __init__(self, cfg: DecisionConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.state = StateExtractor(cfg)
        # HanGrCom's generators, a baseline's messenger, or None (w/o Comm.)
        self.comm: nn.Module | None = scheme(cfg.communication).build(cfg)
        width = cfg.state + cfg.value + cfg.inter
        if not cfg.hierarchical:
            self.direct = DirectPolicy(cfg, width)
            return
        self.subtask = SubTaskPredictor(cfg, width)
        self.subgoal = SubGoalPredictor(cfg)

    def decide(self, sf, inn, inter, x, states=(None, None)):
        """F_a and F_g on (B, T, ·) inputs: logits of every head and the LSTM states."""
        if not self.cfg.hierarchical:
            logits, state = self.direct(torch.cat([sf, inn, inter], dim=-1), states[0])
            return logits, (state, None)
        se, task, s_task = self.subtask(torch.cat([sf, inn, inter], dim=-1), states[0])
        goal, s_goal = self.subgoal(se, x, states[1], task)
        return {**task, **goal}, (s_task, s_goal)


class TeamDecision(nn.Module):
    """The agents of one team (and CentralComm's node), for training on whole episodes."""

    def __init__(self, cfg: DecisionConfig, agents: int) -> None:
        super().__init__()
        self.cfg = cfg
        self.agents = nn.ModuleList(AgentDecision(cfg) for _ in range(agents))
        self.scheme = scheme(cfg.communication)
        self.central = self.scheme.build_central(cfg)  # CentralComm's node; None otherwise

    def forward(
        self, x: list[dict[str, torch.Tensor]], present: torch.Tensor, hard: bool = False,
        labels: list[dict[str, torch.Tensor]] | None = None,
    ) -> tuple[list[dict[str, torch.Tensor]], dict]:  # fmt: skip
        """``x[n]``: agent n's inputs (B, T, ·); ``present`` (B, T, N). Returns per agent the
        logits of every head (B, T, ·), and ``T`` (B, T, N, N; HanGrCom only) with ``aux``,
        the scheme's auxiliary loss (its labels from ``labels``). ``hard``: HanGrCom's
        inference mode (thresholded handshake) instead of the soft one."""
        sf = [agent.state(xn)[0] for agent, xn in zip(self.agents, x, strict=True)]
        inn, inter, info = self._communicate(sf, x, present, hard, labels)
        out = [
            agent.decide(sf[n], inn[:, :, n], inter[:, :, n], x[n])[0]
            for n, agent in enumerate(self.agents)
        ]
        return out, info

    def _communicate(self, sf, x, present, hard, labels):
        """``inn``, ``int`` (B, T, N, ·) and the info ``forward`` returns."""
        comms = [agent.comm for agent in self.agents]
        return self.scheme.communicate(self.cfg, comms, sf, x, present, hard, labels, self.central)
