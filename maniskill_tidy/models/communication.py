"""The communication baselines of the paper (Section 6.3, Fig. 6) as learned modules.

Every scheme gives an agent's F_a the same two inputs as HanGrCom, ``inn`` (value dims) and
``int`` (inter dims), so that a variant differs from the paper's model in its communication
only. What crosses between agents is a vector sent through the counting channel at evaluation
(``policies/message_exchange.py``), built here by the same functions that training runs:

- ``none`` (w/o Comm.): nothing is sent; ``inn`` and ``int`` are zero.
- ``broadcast`` (BroadComm.): every agent sends its state (10) and a map embedding (400, a
  learned projection of its map feature ``sm``) to every teammate; ``inn`` is the mean of what
  it reads of the messages, ``int`` their element-wise max.
- ``cond`` (CondComm.): the same message, sent only while the agent's misplaced-object
  detector finds a misplaced object in view (``mis >= 0.5``).
- ``cmpr`` (CmprComm.): the map embedding goes through the sender's encoder (400 -> 100) and
  the receiver's decoder (100 -> 400), trained with a reconstruction loss besides Eq. 2.
- ``inten`` (IntenComm.): only the state (10), which holds the sender's sub-task; the receiver
  predicts the sender's next sub-goal (dx, dy) with a learned head, trained on the sender's
  labels, and reads the message together with that intention.
- ``central`` (CentralComm.): every agent uploads state and map embedding (410) to a central
  node, which sends each agent an assignment (value dims) computed from all uploads (all but
  the agent's own last sub-task: ``CentralPlanner``); ``inn`` is the assignment. The paper's
  node generates the sub-task itself; here the assignment is what the agent's F_a turns into
  its sub-task, so that F_g reads ``se`` as in every variant.

The state message is the heuristic teams' (``policies/messages.py``) in the model's index
spaces: capability (3), x and y in metres, heading in degrees, and the sub-task the agent
pursued last step (kind, object, receptacle and room indices, -1 for none).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

SCHEMES = ("hangrcom", "none", "broadcast", "cond", "cmpr", "inten", "central")
STATE = 10  # capability 3, x, y, heading, sub-task 4
MAP = 400  # the map embedding (the paper counts the map as 400 values)
COMPRESSED = 100  # CmprComm's code
MISPLACED = 0.5  # CondComm sends while its detector's best probability is at least this
TASK = ("kind", "object", "receptacle", "room")


def state_message(va: torch.Tensor, pose: torch.Tensor, task: torch.Tensor) -> torch.Tensor:
    """(…, STATE): capability (…, 3), pose (…, 4: x, y, heading, pitch) and last step's
    sub-task indices (…, 4, -1 for none)."""
    return torch.cat([va.float(), pose[..., :3].float(), task.float()], dim=-1)


class StateReader(nn.Module):
    """What a receiver makes of a state message: capability, position, heading and sub-task."""

    def __init__(self, cfg, out: int = 64) -> None:
        super().__init__()
        sizes = (2, cfg.objects, cfg.receptacles, cfg.rooms)
        self.task = nn.ModuleList(nn.Embedding(n + 1, 16) for n in sizes)  # index 0: none
        self.fuse = nn.Sequential(nn.Linear(3 + 4 + 16 * len(sizes), out), nn.ReLU())

    def forward(self, m: torch.Tensor) -> torch.Tensor:
        yaw = torch.deg2rad(m[..., 5])
        where = torch.stack([m[..., 3] / 10, m[..., 4] / 10, torch.cos(yaw), torch.sin(yaw)], -1)
        index = m[..., 6:10].round().long().clamp(min=-1) + 1
        task = [emb(index[..., k].clamp(max=emb.num_embeddings - 1))
                for k, emb in enumerate(self.task)]  # fmt: skip
        return self.fuse(torch.cat([m[..., :3], where, *task], dim=-1))


class Messenger(nn.Module):
    """One agent's side of a message-passing scheme: what it sends and how it reads."""

    def __init__(self, cfg) -> None:
        super().__init__()
        self.scheme = cfg.communication
        if self.scheme != "inten":
            self.map = nn.Linear(cfg.perception, MAP)  # the map embedding it sends
        if self.scheme == "central":
            return  # it only uploads: the central node reads
        self.state_reader = StateReader(cfg)
        width = 64 + (MAP if self.scheme != "inten" else 0)
        if self.scheme == "cmpr":
            self.encoder = nn.Linear(MAP, COMPRESSED)
            self.decoder = nn.Linear(COMPRESSED, MAP)
        if self.scheme == "inten":
            self.intent = nn.Linear(64, 9 + 9)  # the sender's next dx and dy
            width += 9 + 9
        self.read = nn.Sequential(nn.Linear(width, cfg.value), nn.ReLU())

    def map_embedding(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.tanh(self.map(x["sm"]))

    def outgoing(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """The message (…, dims) this agent sends in this step."""
        state = state_message(x["va"], x["pose"], x["prev_task"])
        if self.scheme == "inten":
            return state
        m = self.map_embedding(x)
        if self.scheme == "cmpr":
            m = self.encoder(m)
        return torch.cat([state, m], dim=-1)

    def sends(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """(…) bool: whether it sends at all in this step."""
        if self.scheme == "cond":
            return x["mis"] >= MISPLACED
        return torch.ones_like(x["mis"], dtype=torch.bool)

    def incoming(self, m: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """What this agent reads of messages (…, dims): features (…, value) and, for the
        auxiliary losses, the decoded map or the predicted intention."""
        state = self.state_reader(m[..., :STATE])
        extra: dict[str, torch.Tensor] = {}
        if self.scheme == "inten":
            extra["intent"] = self.intent(state)
            intent = extra["intent"]
            parts = [state, intent[..., :9].softmax(-1), intent[..., 9:].softmax(-1)]
        else:
            code = m[..., STATE:]
            extra["map"] = self.decoder(code) if self.scheme == "cmpr" else code
            parts = [state, extra["map"]]
        return self.read(torch.cat(parts, dim=-1)), extra


def pool(features: torch.Tensor, received: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``inn`` (mean) and ``int`` (element-wise max) over the messages received: features
    (…, N, d), received (…, N) bool; zeros where nothing arrived."""
    w = received.to(features.dtype).unsqueeze(-1)
    inn = (features * w).sum(-2) / w.sum(-2).clamp(min=1)
    top = features.masked_fill(~received.unsqueeze(-1), float("-inf")).amax(-2)
    return inn, torch.where(received.any(-1, keepdim=True), top, torch.zeros_like(top))


class CentralPlanner(nn.Module):
    """CentralComm's node: from every agent's upload (state 10 + map 400) an assignment
    (value dims) per agent, from its own upload and its teammates' pooled ones.

    It does not read the sub-task in the agent's own upload. Under behaviour cloning that
    field is the teacher's label of the last step, and a node that reads it learns to copy it
    (95-99.7 % of Setting I val steps keep last step's sub-task, per head:
    ``scripts/label_persistence.py``), then fails on its own sub-tasks at test time. No agent of
    any scheme reads its own last sub-task; teammates' are read wherever messages carry the
    state."""

    def __init__(self, cfg) -> None:
        super().__init__()
        self.state_reader = StateReader(cfg)
        self.read = nn.Sequential(nn.Linear(64 + MAP, 128), nn.ReLU())
        self.assign = nn.Sequential(nn.Linear(3 * 128, cfg.value), nn.ReLU())

    def _read(self, uploads: torch.Tensor) -> torch.Tensor:
        return self.read(torch.cat([self.state_reader(uploads[..., :STATE]),
                                    uploads[..., STATE:]], dim=-1))  # fmt: skip

    def forward(self, uploads: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """uploads (…, N, STATE + MAP), present (…, N) -> assignments (…, N, value)."""
        own = uploads.clone()
        own[..., STATE - len(TASK) : STATE] = -1  # its own last sub-task: withheld
        n = uploads.shape[-2]
        h = self._read(uploads)
        others = present.unsqueeze(-2) & ~torch.eye(n, dtype=torch.bool)  # (…, N, N): i <- j
        mean, top = pool(h.unsqueeze(-3).expand(*h.shape[:-2], n, n, h.shape[-1]), others)
        out = self.assign(torch.cat([self._read(own), mean, top], dim=-1))
        return out * present.unsqueeze(-1).to(out.dtype)


def exchange(
    messengers: list[Messenger], x: list[dict[str, torch.Tensor]], present: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
    """A message-passing scheme over a whole team in training: ``inn`` and ``int``
    (…, N, d) and the per-pair outputs the auxiliary losses need. Agent j's message reaches
    agent i when both are present, i != j and j sends."""
    msgs = torch.stack([m.outgoing(xn) for m, xn in zip(messengers, x, strict=True)], dim=-2)
    sends = torch.stack([m.sends(xn) for m, xn in zip(messengers, x, strict=True)], dim=-1)
    n = len(messengers)
    eye = torch.eye(n, dtype=torch.bool)
    inn, inter, extras = [], [], []
    for i, m in enumerate(messengers):
        feats, extra = m.incoming(msgs)
        received = sends & present & present[..., i : i + 1] & ~eye[i]
        a, b = pool(feats, received)
        inn.append(a)
        inter.append(b)
        extras.append({**extra, "received": received})
    out = {"pairs": extras, "messages": msgs}
    if messengers[0].scheme == "cmpr":  # what the decoders should give back
        out["sent_map"] = torch.stack(
            [m.map_embedding(xn) for m, xn in zip(messengers, x, strict=True)], -2
        )
    return torch.stack(inn, -2), torch.stack(inter, -2), out


def auxiliary_loss(
    messengers: list[Messenger], extras: dict, ys: list[dict[str, torch.Tensor]] | None
) -> torch.Tensor:
    """CmprComm: reconstruct the sender's map embedding from its code; IntenComm: predict the
    sender's sub-goal (dx, dy) labels. Zero for the other schemes."""
    total = torch.zeros(())
    scheme = messengers[0].scheme
    if scheme not in ("cmpr", "inten"):
        return total
    for pair in extras["pairs"]:
        ok = pair["received"]
        if not ok.any():
            continue
        if scheme == "cmpr":
            total = total + F.mse_loss(pair["map"][ok], extras["sent_map"].detach()[ok])
        elif ys is not None:
            for k, head in enumerate(("dx", "dy")):
                y = torch.stack([yj[head] for yj in ys], dim=-1)  # (…, N) sender labels
                logits = pair["intent"][..., 9 * k : 9 * (k + 1)]
                mask = ok & (y >= 0)
                if mask.any():
                    total = total + F.cross_entropy(logits[mask], y[mask])
    return total
