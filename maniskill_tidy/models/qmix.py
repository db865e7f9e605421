"""QMIX (Rashid et al., 2018) for the paper's QMIX baseline (Section 6.3).

Each agent has its own recurrent Q-network (heterogeneous agents share no weights). It encodes
its own observation features into a state feature, receives its teammates' state features
(through the channel at evaluation: 256 values from each), fuses them with its own and predicts
the Q-value of each of the env's 11 low-level actions. A monotonic mixing network (TorchRL's
``QMixer``: hypernetworks of the global state with absolute weights) sums the chosen actions'
values into the team's Q_tot, trained by TD on whole episodes (``training/qmix_trainer.py``).

The observation is the frozen perception's output for the agent's own frame, as the other
learned agents get it: capability, pose, held-or-not, own failure, the detector's probability
and whether there was a detection, and the 256-d sv, sm, fd and fp.
"""

from __future__ import annotations

import torch
from torch import nn

from maniskill_tidy.envs.actions import Action
from maniskill_tidy.models.decision import POSE, encode_pose

FEATURES = ("sv", "sm", "fd", "fp")
SMALL = 3 + POSE + 4  # capability, pose, holding, failed, misplaced probability, detection
OBS = SMALL + 256 * len(FEATURES)
ACTIONS = len(Action)


def observation(x: dict[str, torch.Tensor]) -> torch.Tensor:
    """(…, OBS) from a learned agent's inputs (``PerceivingAgent.perceive``; rows of the
    features cache have the same keys)."""
    small = [x["va"].float(), encode_pose(x["pose"].float()), (x["held"] >= 0).float()[..., None],
             x["failed"].float()[..., None], x["mis"].float()[..., None],
             x["det"].float()[..., None]]  # fmt: skip
    return torch.cat([*small, *(x[k].float() for k in FEATURES)], dim=-1)


def global_state(obs: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
    """The mixer's state (…, N * SMALL): every agent's small observation (zeros when absent)."""
    return (obs[..., :SMALL] * present.unsqueeze(-1).to(obs.dtype)).flatten(-2)


class AgentQ(nn.Module):
    """One agent: observation -> state feature; (own, teammates') features -> GRU -> Q."""

    def __init__(self, teammates: int, feature: int = 256, hidden: int = 128) -> None:
        super().__init__()
        self.encode = nn.Sequential(nn.Linear(OBS, feature), nn.ReLU())  # what it sends
        self.fuse = nn.Sequential(nn.Linear(feature * (1 + teammates), hidden), nn.ReLU())
        self.rnn = nn.GRUCell(hidden, hidden)
        self.q = nn.Linear(hidden, ACTIONS)
        self.hidden = hidden

    def forward(self, own: torch.Tensor, others: torch.Tensor, h: torch.Tensor | None = None):
        """own (B, feature), others (B, teammates, feature), h (B, hidden) -> Q (B, 11), h."""
        z = self.fuse(torch.cat([own, others.flatten(1)], dim=-1))
        h = self.rnn(z, h)
        return self.q(h), h


class QmixTeamModel(nn.Module):
    """The agents' Q-networks and the mixer of one team."""

    def __init__(self, agents: int, feature: int = 256, hidden: int = 128, mixing: int = 32):
        super().__init__()
        self.n, self.feature = agents, feature
        self.agents = nn.ModuleList(AgentQ(agents - 1, feature, hidden) for _ in range(agents))
        from torchrl.modules import QMixer  # here: torchrl takes seconds to import

        self.mixer = QMixer((agents * SMALL,), mixing, agents, "cpu")

    def others(self, features: torch.Tensor, present: torch.Tensor, i: int) -> torch.Tensor:
        """Agent i's view of the teammates' features (…, N - 1, feature): zeros from agents
        that have stopped (they send nothing)."""
        f = features * present.unsqueeze(-1).to(features.dtype)
        return torch.cat([f[..., :i, :], f[..., i + 1 :, :]], dim=-2)

    def q_values(self, obs: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """Unrolled over whole episodes: obs (B, T, N, OBS), present (B, T, N) -> Q (B, T, N,
        11)."""
        b, t = obs.shape[:2]
        features = torch.stack([a.encode(obs[:, :, i]) for i, a in enumerate(self.agents)], 2)
        hs = [None] * self.n
        out = []
        for step in range(t):
            qs = []
            for i, agent in enumerate(self.agents):
                others = self.others(features[:, step], present[:, step], i)
                q, hs[i] = agent(features[:, step, i], others, hs[i])
                qs.append(q)
            out.append(torch.stack(qs, 1))
        return torch.stack(out, 1)

    def mix(self, chosen: torch.Tensor, obs: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """Q_tot (…) from the chosen actions' values (…, N); absent agents add nothing."""
        chosen = chosen * present.to(chosen.dtype)
        return self.mixer(chosen.unsqueeze(-1), global_state(obs, present)).squeeze(-1)
