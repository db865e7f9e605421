"""The paper's learned team: perception -> F_s -> HanGrCom -> F_a -> F_g -> sub-goal executor.

Each agent runs alone on its own observation (``AgentView``) and its inbox. Every env step is a
sub-goal step: the agent reads its frame (``perception/frame_inputs.py``), runs the frozen
perception model and its own decision model (``models/decision.py``), exchanges HanGrCom's
vectors through the counting channel, predicts a sub-task and a sub-goal and takes the first
action towards the sub-goal (``policies/executor.py``). Re-predicting every step is this
project's choice (the paper does not say); every learned variant uses it, and it is why
AvgCom counts HanGrCom's vectors per env step, as the broadcast baseline's 410 x (N - 1).

Communication per step: three rounds of ``policies/handshake_exchange.py`` (queries, rows of T,
then values and inter-group vectors along the handshake's links). Every vector crosses the
channel, so AvgCom counts all of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import torch

from maniskill_tidy.envs.actions import MIN_PIXELS, REACH, Action, AgentState, Targeted
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.models.decision import crop_goal, crop_layout
from maniskill_tidy.perception.frame_inputs import FrameInputs, FrameReader
from maniskill_tidy.policies.base import (
    EXPLORE,
    OPERATIONS,
    PLACE,
    Agent,
    AgentView,
    Label,
    PublicInfo,
    SubGoal,
    SubTask,
    Team,
)
from maniskill_tidy.policies.channel import Message, Outbox
from maniskill_tidy.policies.executor import SubGoalExecutor, goal_cell, relative
from maniskill_tidy.policies.handshake_exchange import HandshakeExchange
from maniskill_tidy.policies.navigation import GridPlanner
from maniskill_tidy.tasks.teams import SETTINGS

REPO = Path(__file__).resolve().parents[2]
COMMIT_STEPS = 4  # env steps a sub-goal is pursued before a new prediction replaces it
DEFAULT_CONFIG = Path("agents/hangrcom.yaml")


def resolve(path: str | Path) -> Path:
    """A path as given (absolute, or relative to the working directory), else under the repo."""
    path = Path(path)
    return path if path.is_absolute() or path.exists() else REPO / path


@dataclass
class Decision:
    subtask: SubTask
    subgoal: SubGoal


def decode(logits: dict[str, torch.Tensor]) -> Decision:
    """The argmax of every head, as the paper's sub-task and sub-goal."""
    catalog = load_catalog()
    best = {k: int(v.reshape(-1, v.shape[-1])[-1].argmax()) for k, v in logits.items()}
    kind = PLACE if best["kind"] == 1 else EXPLORE
    subtask = SubTask(
        kind, catalog.pickupable[best["object"]], catalog.receptacles[best["receptacle"]],
        ROOM_TYPES[best["room"]],
    )  # fmt: skip
    subgoal = SubGoal(best["dx"] - 4, best["dy"] - 4, best["drot"] * 90,
                      OPERATIONS[best["ope"]], bool(best["stop"]))  # fmt: skip
    return Decision(subtask, subgoal)


class LearnedAgent(Agent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, team: LearnedTeam) -> None:
        super().__init__(name, public, outbox)
        model, self.perception = team.models(public.capabilities)
        self.i = public.agents.index(name)
        self.decision = model.agents[self.i]
        self.exchange = HandshakeExchange(
            name, public.agents, outbox, model.cfg.mu, model.cfg.delta
        )
        self.reader = FrameReader(public.house, public.instances)
        self.planner = GridPlanner(public.house)
        rng = np.random.default_rng([public.seed, self.i, 11])
        self.executor = SubGoalExecutor(self.planner, rng)
        self.capability = public.capability(name)
        self.state = AgentState(name, self.capability, (0, 0), 0)
        self.lstm: tuple = (None, None, None)  # F_s, F_a, F_g
        self.furniture = public.house.furniture_by_id()
        self.t = 0
        self._label: Label | None = None
        self._trace: dict = {}
        self._last_op: Action | None = None
        self.commit: tuple | None = None  # (cell, rotation, ope, stop, subtask, since step)

    # ------------------------------------------------------------------ perception
    def observe(self, view: AgentView) -> None:
        o, s = view.obs, self.state
        self.t = view.step
        s.cell = self.public.house.navgrid.cell_of(float(o["pose"][0]), float(o["pose"][1]))
        s.rotation = int(round(float(o["pose"][2]))) % 360
        self.frame = f = self.reader.read(o)
        s.horizon = int(f.pose[3])
        s.held = self.public.instances[int(o["held"])].id if int(o["held"]) else None
        if view.failed:
            self.executor.failed(s, view.failed, self.t)
        self.failed = bool(view.failed)
        self.seg = np.asarray(o["segmentation"])
        feats = self.perception.step_features(
            torch.from_numpy(f.rgb[None]), torch.from_numpy(f.seen[None]),
            torch.from_numpy(f.crop[None]), torch.zeros(len(f.det_type), dtype=torch.long),
            torch.from_numpy(f.det_type), torch.from_numpy(f.det_rest),
            torch.from_numpy(f.det_numeric),
        )  # fmt: skip
        self.p_detections = feats["p_detections"].numpy()
        x = {k: feats[k][None] for k in ("sv", "sm", "fd", "fp", "mis", "det")}
        x.update(
            va=torch.tensor([[self.capability]], dtype=torch.float32),
            pose=torch.from_numpy(f.pose)[None, None],
            held=torch.tensor([[f.held]]),
            failed=torch.tensor([[float(self.failed)]]),
        )
        if self.decision.cfg.layout:
            x["layout"] = torch.from_numpy(crop_layout(f.crop))[None, None]
        if self.decision.cfg.goal_map:
            x["goal"] = torch.from_numpy(crop_goal(f.crop))[None, None]
        self.x = x
        with torch.no_grad():
            sf, state = self.decision.state(x, self.lstm[0])
            self.lstm = (state, *self.lstm[1:])
            self.sf = sf
            self.gens = {k: v[0, 0] for k, v in self.decision.comm(sf).items()}

    # ------------------------------------------------------------------ HanGrCom
    def send(self, round: int, inbox: list[Message]) -> None:
        self.exchange.send(round, inbox, self.gens)

    # ------------------------------------------------------------------ deciding and acting
    def act(self, inbox: list[Message]) -> Action | Targeted:
        inn, inter = self.exchange.combine(inbox, self.gens)
        with torch.no_grad():
            logits, states = self.decision.decide(
                self.sf, inn[None, None], inter[None, None], self.x, self.lstm[1:]
            )
        self.lstm = (self.lstm[0], *states)
        d = decode(logits)
        self._label = (d.subtask, d.subgoal)
        ex = self.exchange
        self._trace = {"T": ex.T, "groups": ex.groups(), "links": ex.links()}
        action = self._act(d)
        self._last_op = action.action if isinstance(action, Targeted) else action
        return action

    def _act(self, d: Decision) -> Action | Targeted:
        """Pursue the committed sub-goal (a new prediction is adopted once it is reached, or
        after COMMIT_STEPS steps): re-adopting every step makes agents dither."""
        s = self.state
        if self.commit is None or self.t - self.commit[-1] >= COMMIT_STEPS:
            g = d.subgoal
            cell = goal_cell(s, g)
            self.commit = (cell, (s.rotation + g.drot) % 360, g.ope, g.stop, d.subtask, self.t)
        cell, rotation, ope, stop, subtask, _ = self.commit
        goal = relative(s, cell, rotation, ope, stop)
        move = self.executor.move(s, goal, self.t)
        if move is not None:
            return move
        self.commit = None  # reached: the next step adopts a new prediction
        # an operation that just failed here: look elsewhere before trying it again
        retry = self.failed and self._last_op in (Action.PickUp, Action.PutDown)
        if self.capability[1] and ope != "NoAction" and not retry:
            op = None
            if ope == "PickUp" and s.held is None:
                op = self._pick(subtask)
            elif ope == "PutDown" and s.held is not None:
                op = self._put(subtask)
            elif ope == "Drop" and s.held is not None:
                op = Action.Drop
            if op is not None:
                return op
        if stop:
            return Action.Stop
        return self.executor.look(s)

    def _pick(self, subtask: SubTask) -> Targeted | None:
        """The detected object in reach of the predicted type (else the likeliest misplaced)."""
        f: FrameInputs = self.frame
        here = np.asarray(self.public.house.navgrid.center(*self.state.cell))
        near = [i for i in range(len(f.det_object))
                if np.hypot(*(f.det_position[i, :2] - here)) <= REACH]  # fmt: skip
        if not near:
            return None  # nothing to pick up in reach: not worth a failed action
        kind = load_catalog().categories
        same = [i for i in near if kind[f.det_type[i]] == subtask.object_type]
        best = max(same or near, key=lambda i: self.p_detections[i])
        return Targeted(Action.PickUp, f.det_object[best])

    def _put(self, subtask: SubTask) -> Action | Targeted | None:
        """A visible surface of the predicted receptacle type, else the env's choice among the
        visible furniture, or None when no furniture is in view."""
        ids, counts = np.unique(self.seg, return_counts=True)
        furniture = False
        for sid, n in sorted(zip(ids, counts, strict=True), key=lambda p: -p[1]):
            inst = self.public.instances.get(int(sid))
            if inst is None or inst.kind != "furniture" or n < MIN_PIXELS:
                continue
            f = self.furniture.get(inst.id.split("/")[0])
            furniture = True
            for surface in f.surfaces if f is not None else []:
                if surface.receptacle_type == subtask.receptacle_type:
                    return Targeted(Action.PutDown, f"{f.id}/{surface.name}")
        return Action.PutDown if furniture else None

    def label(self) -> Label | None:
        return self._label

    def trace(self) -> dict:
        return self._trace


class LearnedTeam(Team):
    """A team of learned agents from an agent config (``agents/*.yaml``)."""

    name = "hangrcom"
    observations = "rgb+depth+segmentation"
    communication = "hangrcom"
    rounds = 3
    perception: ClassVar[str] = (
        "learned: small CNNs and GCN (agents/perception) over ground-truth segmentation, "
        "open3d semantic map; behaviour-cloned HanGrCom decision"
    )

    config_file: ClassVar[Path] = DEFAULT_CONFIG

    def __init__(self, config: str | Path | None = None) -> None:
        from maniskill_tidy.training.decision_trainer import AgentConfig

        self.config_path = resolve(config or self.config_file)
        self.config = AgentConfig.load(self.config_path)
        self._loaded: dict = {}

    def models(self, capabilities: list) -> tuple:
        """The decision model trained for this team, and the frozen perception model."""
        from maniskill_tidy.training.decision_trainer import load_model
        from maniskill_tidy.training.perception_trainer import load_agent

        team = tuple(tuple(c) for c in capabilities)
        setting = next((s for s, members in SETTINGS.items() if members == team), None)
        if setting is None:
            raise ValueError(
                f"{self.config.name} is trained for the teams of Settings {sorted(SETTINGS)}, "
                f"not {list(team)}"
            )
        if setting not in self._loaded:
            # Batch-of-one inference: one thread is fastest, and several contend with the
            # other evaluation workers (measured 2-20 x slower on 2 busy cores).
            torch.set_num_threads(1)
            model, _ = load_model(resolve(self.config.out) / f"setting_{setting}")
            perception = load_agent(resolve(self.config.perception))
            self._loaded[setting] = (model, perception)
        return self._loaded[setting]

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return LearnedAgent(name, public, outbox, self)


def learned_team_class(config: str | Path) -> type[LearnedTeam]:
    """A team class named after an agent config's ``name`` (``eval --policy CONFIG.yaml``)."""
    from maniskill_tidy.training.decision_trainer import AgentConfig

    cfg = AgentConfig.load(resolve(config))
    attrs = {"name": cfg.name, "config_file": resolve(config)}
    return type(f"LearnedTeam_{cfg.name}", (LearnedTeam,), attrs)
