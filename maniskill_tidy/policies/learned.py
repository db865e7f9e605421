"""The paper's learned team: perception -> F_s -> HanGrCom -> F_a -> F_g -> sub-goal executor.

Each agent runs alone on its own observation (``AgentView``) and its inbox. At a sub-goal step
the agent reads its frame (``perception/frame_inputs.py``), runs the frozen perception model and
its own decision model (``models/decision.py``), exchanges HanGrCom's vectors through the
counting channel, predicts a sub-task and a sub-goal and takes the first action towards the
sub-goal (``policies/executor.py``); between sub-goal steps it only reads its frame into its map
and pursues the sub-goal. The shipped models make every env step a sub-goal step (the paper
does not say how often; ``DecisionConfig.decide_every`` sets it), which is why AvgCom counts
their HanGrCom vectors per env step, as the broadcast baseline's 410 x (N - 1).

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

from maniskill_tidy.common.agent_files import resolve
from maniskill_tidy.envs.actions import REACH, Action, Targeted
from maniskill_tidy.envs.robots import robot_kind
from maniskill_tidy.knowledge import ROOM_TYPES, load_catalog
from maniskill_tidy.models.checkpoints import (
    CheckpointError,
    for_agents,
    load_decision,
    load_perception,
    verify,
    weights_digest,
)
from maniskill_tidy.models.communication import TASK, scheme
from maniskill_tidy.models.decision import DecisionConfig, crop_layout, goal_maps, suspects
from maniskill_tidy.policies.agent_config import AgentConfig, PerceptionLook, perception_look
from maniskill_tidy.policies.base import (
    EXPLORE,
    OPERATIONS,
    PLACE,
    Agent,
    AgentView,
    CentralNode,
    Label,
    PublicInfo,
    SubGoal,
    SubTask,
    Team,
)
from maniskill_tidy.policies.channel import Message, Outbox
from maniskill_tidy.policies.executor import goal_cell, relative
from maniskill_tidy.policies.handshake_exchange import HandshakeExchange
from maniskill_tidy.policies.message_exchange import LearnedCentral, MessageExchange
from maniskill_tidy.policies.perceiving import PerceivingAgent
from maniskill_tidy.policies.viewpoints import viewpoints
from maniskill_tidy.policies.walker import Leg, NoViewpoint, Walker
from maniskill_tidy.tasks.teams import SETTINGS, setting_of

COMMIT_STEPS = 4  # env steps a sub-goal is pursued before a new prediction replaces it
DEFAULT_CONFIG = Path("agents/hangrcom.yaml")


@dataclass
class Decision:
    subtask: SubTask
    subgoal: SubGoal


def decode(
    logits: dict[str, torch.Tensor],
    ope_threshold: float | None = None,
    rng: np.random.Generator | None = None,
    temperature: float = 1.0,
) -> Decision:
    """The argmax of every head, as the paper's sub-task and sub-goal; with ``ope_threshold``
    the likeliest operation wherever its probability exceeds the threshold; with ``rng``
    dx, dy and drot drawn from their heads, sharpened by a ``temperature`` below 1."""
    catalog = load_catalog()
    best = {k: int(v.reshape(-1, v.shape[-1])[-1].argmax()) for k, v in logits.items()}
    if rng is not None:
        for head in ("dx", "dy", "drot"):
            z = logits[head].reshape(-1, logits[head].shape[-1])[-1].double()
            p = (z / temperature).softmax(-1)
            best[head] = int(rng.choice(len(p), p=(p / p.sum()).numpy()))
    if ope_threshold is not None:
        p = logits["ope"].reshape(-1, len(OPERATIONS))[-1].softmax(-1)
        op = int(p[1:].argmax()) + 1
        if float(p[op]) > ope_threshold:
            best["ope"] = op
    kind = PLACE if best["kind"] == 1 else EXPLORE
    subtask = SubTask(
        kind, catalog.pickupable[best["object"]], catalog.receptacles[best["receptacle"]],
        ROOM_TYPES[best["room"]],
    )  # fmt: skip
    subgoal = SubGoal(best["dx"] - 4, best["dy"] - 4, best["drot"] * 90,
                      OPERATIONS[best["ope"]], bool(best["stop"]))  # fmt: skip
    return Decision(subtask, subgoal)


def task_indices(logits: dict[str, torch.Tensor]) -> torch.Tensor:
    """The predicted sub-task as the labels index it (kind, object, receptacle, room; object
    and receptacle -1 in an Explore sub-task): what a state message carries next step."""
    best = [int(logits[k].reshape(-1, logits[k].shape[-1])[-1].argmax()) for k in TASK]
    if best[0] == 0:  # Explore
        best[1] = best[2] = -1
    return torch.tensor(best)


class LearnedAgent(PerceivingAgent):
    def __init__(self, name: str, public: PublicInfo, outbox: Outbox, team: LearnedTeam) -> None:
        model, perception = team.models(public.capabilities)
        i = public.agents.index(name)
        self.decision = model.agents[i]
        super().__init__(
            name, public, outbox, perception, model.cfg.misplaced_detector,
            wide=model.cfg.wide_layout,
        )  # fmt: skip
        self.protocol = model.scheme.protocol
        self.exchange: HandshakeExchange | MessageExchange | None = None
        if self.protocol == "handshake":
            self.exchange = HandshakeExchange(
                name, public.agents, outbox, model.cfg.mu, model.cfg.delta
            )
        elif self.protocol == "messages":
            self.exchange = MessageExchange(
                name, outbox, self.decision.comm, model.cfg.value, model.cfg.inter
            )
        self.prev_task = torch.full((4,), -1)  # the sub-task it pursued last step (indices)
        self.lstm: tuple = (None, None, None)  # F_s, F_a, F_g
        self._label: Label | None = None
        self._trace: dict = {}
        self.commit: tuple | None = None  # (cell, rotation, ope, stop, subtask, since step)
        self.operation: tuple[str, SubTask] | None = None  # the last sub-goal step's
        acting = team.config.acting()
        # a sub-goal step every `every` env steps, the whole team in step: only then does an
        # agent run its models and exchange HanGrCom's vectors (DecisionConfig.decide_every)
        self.decide_every = acting.decide_every or self.decision.cfg.decide_every
        if self.decide_every > 1 and (acting.oracle or team.central or self.protocol == "messages"):
            raise ValueError(
                f"decide_every {self.decide_every}: only for teams without an oracle, a central "
                "node or per-step state messages (expected 1 for this config)"
            )
        self.deciding = True  # this step is a sub-goal step
        self.ope_threshold = acting.ope_threshold
        self.temperature = acting.subgoal_temperature
        self.sampler = (
            np.random.default_rng([public.seed, self.i, 13]) if acting.sample_subgoal else None
        )
        # SA(Oracle): the misplaced objects still to pick up, and the walk to one of them
        self.oracle = acting.oracle
        self.targets = dict(public.oracle_misplaced)
        self.types = {inst.id: inst.type for inst in public.instances.values()}
        self.fetching: tuple[str, Leg] | None = None
        self.walker = Walker(self.planner)

    # ------------------------------------------------------------------ perception
    def observe(self, view: AgentView) -> None:
        self.deciding = view.step % self.decide_every == 0
        if not self.deciding:  # between sub-goal steps: the map only
            self.read(view)
            self._trace = {}
            return
        x = self.perceive(view)
        if self.oracle:  # it knows which objects in view are misplaced and not yet moved
            self.targets.pop(self.state.held, None)
            self.p_detections = np.array([float(o in self.targets) for o in self.frame.det_object])
        x["prev_task"] = self.prev_task[None, None]
        f = self.frame
        if self.decision.cfg.layout:
            x["layout"] = torch.from_numpy(crop_layout(f.crop))[None, None]
        if self.decision.cfg.goal_map:
            x["goal_maps"] = torch.from_numpy(goal_maps(f.crop))[None, None].float()
        if self.decision.cfg.wide_layout:
            x["wide"] = torch.from_numpy(f.wide)[None, None]
        if self.decision.cfg.suspects:
            x["suspect"] = suspects(
                torch.zeros(len(f.det_type), dtype=torch.long), torch.from_numpy(f.det_type),
                torch.from_numpy(self.p_detections), 1, self.decision.cfg.objects,
            )[None]  # fmt: skip
        self.x = x
        with torch.inference_mode():
            sf, state = self.decision.state(x, self.lstm[0])
            self.lstm = (state, *self.lstm[1:])
            self.sf = sf
            if self.protocol == "handshake":  # its query, key, value and inter vector
                self.gens = {k: v[0, 0] for k, v in self.decision.comm(sf).items()}

    # ------------------------------------------------------------------ communication
    def send(self, round: int, inbox: list[Message]) -> None:
        if not self.deciding:
            return
        if isinstance(self.exchange, HandshakeExchange):
            self.exchange.send(round, inbox, self.gens)
        elif self.exchange is not None:
            self.exchange.send(round, self.x)

    def _received(self, inbox: list[Message]) -> tuple[torch.Tensor, torch.Tensor]:
        """``inn`` and ``int`` from this step's inbox (zeros without communication)."""
        if isinstance(self.exchange, HandshakeExchange):
            return self.exchange.combine(inbox, self.gens)
        if self.exchange is not None:
            return self.exchange.combine(inbox)
        cfg = self.decision.cfg
        return torch.zeros(cfg.value), torch.zeros(cfg.inter)

    # ------------------------------------------------------------------ deciding and acting
    def act(self, inbox: list[Message]) -> Action | Targeted:
        if not self.deciding:  # pursue the sub-goal of the last sub-goal step
            action = self._quiet_operation() or self._pursue()
            self._last_op = action.action if isinstance(action, Targeted) else action
            return action
        inn, inter = self._received(inbox)
        with torch.inference_mode():
            logits, states = self.decision.decide(
                self.sf, inn[None, None], inter[None, None], self.x, self.lstm[1:]
            )
        self.lstm = (self.lstm[0], *states)
        self.p_receptacle = logits["receptacle"].reshape(-1, logits["receptacle"].shape[-1])[-1]
        self.p_receptacle = self.p_receptacle.softmax(-1).numpy()
        if not self.decision.cfg.hierarchical:
            action = self._act_direct(logits["action"].reshape(-1, len(Action))[-1])
            self._last_op = action.action if isinstance(action, Targeted) else action
            return action
        d = decode(logits, self.ope_threshold, self.sampler, self.temperature)
        self.operation = (d.subgoal.ope, d.subtask)
        self.prev_task = task_indices(logits)
        self._label = (d.subtask, d.subgoal)
        ex = self.exchange
        if isinstance(ex, HandshakeExchange):
            self._trace = {"T": ex.T, "groups": ex.groups(), "links": ex.links()}
        action = (self._fetch() if self.oracle else None) or self._act(d)
        self._last_op = action.action if isinstance(action, Targeted) else action
        return action

    def _fetch(self) -> Action | Targeted | None:
        """SA(Oracle), with nothing in hand: walk to the nearest misplaced object still to pick
        up (its location given) and pick it up; None when there is none left to fetch."""
        s = self.state
        if s.held is not None or not self.capability[1]:
            return None
        here = np.asarray(self.public.house.navgrid.center(*s.cell))
        while self.targets:
            if self.fetching is not None and self.fetching[0] not in self.targets:
                self.fetching = None  # picked up (observe drops it from the targets)
            if self.fetching is None:
                oid = min(self.targets, key=lambda o: np.hypot(*(self.targets[o][:2] - here)))
                height = robot_kind(self.capability).camera_height
                spots = viewpoints(self.public.house, np.asarray(self.targets[oid]), height,
                                   side_views=True)[:12]  # fmt: skip
                self.fetching = (oid, Leg(spots))
            oid, leg = self.fetching
            if self.failed and self._last_op == Action.PickUp:
                leg.give_up_goal()  # the pick failed from here: the next viewpoint
            try:
                move = self.walker.step(s, leg, set(), set())
            except NoViewpoint:
                self.targets.pop(oid)
                self.fetching = None
                continue
            if move is not None:
                return move
            pick = self._pick(SubTask(PLACE, object_type=self.types.get(oid, "")))
            if pick is not None:
                return pick
            leg.give_up_goal()  # not in view from here
            return self.executor.look(s)
        return None

    def _act(self, d: Decision) -> Action | Targeted:
        """Pursue the committed sub-goal (a new prediction is adopted once it is reached, or
        after COMMIT_STEPS steps): re-adopting every step makes agents dither. With an
        ``ope_threshold`` a predicted operation that is possible now is done at once."""
        s = self.state
        if self.ope_threshold is not None:
            op = self._operation(d.subgoal.ope, d.subtask)
            if op is not None:
                self.commit = self.operation = None
                return op
        if self.commit is None or self.t - self.commit[-1] >= max(COMMIT_STEPS, self.decide_every):
            g = d.subgoal
            cell = goal_cell(s, g)
            self.commit = (cell, (s.rotation + g.drot) % 360, g.ope, g.stop, d.subtask, self.t)
        return self._pursue()

    def _quiet_operation(self) -> Targeted | Action | None:
        """Between sub-goal steps, the last sub-goal step's operation once it can succeed: an
        agent deciding every step would do it then (``ope_threshold``), and one deciding every
        k steps would otherwise walk past it for up to k - 1 steps. The perception model runs
        (for PickUp's misplaced probabilities) only when an object is in reach."""
        if self.ope_threshold is None or self.operation is None:
            return None
        ope, subtask = self.operation
        f = self.frame
        if ope == "PickUp" and not self._featured:
            here = np.asarray(self.public.house.navgrid.center(*self.state.cell))
            if not (np.hypot(*(f.det_position[:, :2] - here).T) <= REACH).any():
                return None
        op = self._operation(ope, subtask)
        if op is not None:
            self.commit = self.operation = None  # done: the next sub-goal step decides anew
        return op

    def _pursue(self) -> Action | Targeted:
        """A step towards the committed sub-goal; once there its operation, Stop, or a look
        around (also what an agent does between sub-goal steps when it has none)."""
        s = self.state
        if self.commit is None:
            return self.executor.look(s)
        cell, rotation, ope, stop, subtask, _ = self.commit
        goal = relative(s, cell, rotation, ope, stop)
        move = self.executor.move(s, goal, self.t)
        if move is not None:
            return move
        self.commit = None  # reached: the next step adopts a new prediction
        op = self._operation(ope, subtask)
        if op is not None:
            return op
        if stop:
            return Action.Stop
        return self.executor.look(s)

    def _act_direct(self, logits: torch.Tensor) -> Action | Targeted:
        """w/o HierDec.: the likeliest low-level action (drawn, with ``sample_subgoal``) that
        the agent can take; an operation with nothing to operate on gives way to the next."""
        p = logits.double().softmax(-1).numpy()
        if not self.capability[1]:
            p[int(Action.PickUp) :] = 0
        options = np.flatnonzero(p > 0)
        if self.sampler is not None:
            order = self.sampler.choice(options, len(options), replace=False,
                                        p=p[options] / p[options].sum())  # fmt: skip
        else:
            order = options[np.argsort(-p[options], kind="stable")]
        for a in map(Action, map(int, order)):
            if a < Action.PickUp:
                return a
            op = self._operation(a.name, SubTask(EXPLORE))
            if op is not None:
                return op
        return Action.RotateLeft  # unreachable: the navigation actions are always possible

    def label(self) -> Label | None:
        return self._label

    def trace(self) -> dict:
        return self._trace


def describe(perception: str, decision: DecisionConfig) -> str:
    """The runs table's line for a variant: its perception and what its decision leaves out."""
    cut = [name for name, kept in (("misplaced-object detector", decision.misplaced_detector),
                                   ("receptacle predictor", decision.receptacle_predictor))
           if not kept]  # fmt: skip
    comm = scheme(decision.communication).label
    kind = "hierarchical" if decision.hierarchical else "low-level (no sub-tasks)"
    return (
        f"learned: small CNNs and GCN ({perception}) over ground-truth segmentation, open3d "
        f"semantic map; behaviour-cloned {kind} decision, {comm}"
        + "".join(f", without {c}" for c in cut)
    )


class LearnedTeam(Team):
    """A team of learned agents from an agent config (``agents/*.yaml``)."""

    name = "hangrcom"
    observations = "rgb+depth+segmentation"
    communication = "hangrcom"
    rounds = 3
    threadsafe_agents = True
    agent_processes = True
    perception: ClassVar[str] = describe("agents/perception/knowledge", DecisionConfig())
    look: ClassVar[str | None] = PerceptionLook(AgentConfig.perception)  # its views': v1

    config_file: ClassVar[Path] = DEFAULT_CONFIG

    def __init__(self) -> None:
        self.config = AgentConfig.load(resolve(self.config_file))
        self._loaded: dict = {}

    @classmethod
    def trained_setting(cls, capabilities) -> str:
        """The setting whose model plays this team of capabilities."""
        team = tuple(tuple(c) for c in capabilities)
        if cls.team_override and team == tuple(map(tuple, cls.team_override)):
            return "I"  # a team of its own (SA) is trained once, on Setting I's episodes
        setting = setting_of(team)
        if setting is None:
            raise ValueError(
                f"{cls.name} is trained for the teams of Settings {sorted(SETTINGS)}, "
                f"not {list(team)}"
            )
        return setting

    @classmethod
    def model_folder(cls, team) -> Path:
        """Where the decision model that plays this team of capabilities is saved."""
        out = AgentConfig.load(resolve(cls.config_file)).out
        return resolve(out) / f"setting_{cls.trained_setting(team)}"

    @classmethod
    def missing_model(cls, team: tuple) -> str | None:
        """Why this team cannot play (its decision or perception weights missing, damaged or
        not the ones their card describes), or None; checked before a run writes anything."""
        setting = cls.trained_setting(team)
        cfg = AgentConfig.load(resolve(cls.config_file))
        # an oracle acts with another config's model (SA(Oracle): agents/sa.yaml's)
        config = f"{cfg.out}.yaml" if cls.oracle else cls.config_file
        try:
            verify(cls.model_folder(team), f"maniskill-tidy train {config} --setting {setting}",
                   "make train-all")  # fmt: skip
            look = perception_look(cfg.perception)
            verify(resolve(cfg.perception), f"maniskill-tidy train perception --env {look}")
        except CheckpointError as err:
            return str(err)
        return None

    @classmethod
    def model_hash(cls, team: tuple) -> str:
        """A fingerprint of the weights this team plays with (decision and perception): an eval
        run resumed after a retraining that changed them is refused rather than mixing two
        models."""
        cfg = AgentConfig.load(resolve(cls.config_file))
        return weights_digest(cls.model_folder(team), resolve(cfg.perception))

    def models(self, capabilities: list) -> tuple:
        """The decision model trained for this team, and the frozen perception model."""

        setting = self.trained_setting(capabilities)
        if setting not in self._loaded:
            # Batch-of-one inference: one thread is fastest, and several contend with the
            # other evaluation workers (measured 2-20 x slower on 2 busy cores).
            torch.set_num_threads(1)
            model, _ = load_decision(self.model_folder(capabilities))
            perception = load_perception(resolve(self.config.perception))
            self._loaded[setting] = (for_agents(model), for_agents(perception))
        return self._loaded[setting]

    def make_agent(self, name: str, public: PublicInfo, outbox: Outbox) -> Agent:
        return LearnedAgent(name, public, outbox, self)

    def make_central(self, public: PublicInfo, outbox: Outbox) -> CentralNode | None:
        model, _ = self.models(public.capabilities)
        return LearnedCentral(public, outbox, model.central) if model.central else None


def learned_team_class(config: str | Path) -> type[LearnedTeam]:
    """A team class named after an agent config's ``name`` (``eval --policy CONFIG.yaml``)."""

    cfg = AgentConfig.load(resolve(config))
    decision = cfg.decision()
    comm = scheme(decision.communication)
    attrs = {"name": cfg.name, "config_file": resolve(config), "communication": comm.name,
             "perception": describe(cfg.perception, decision),
             "look": PerceptionLook(cfg.perception),
             "central": comm.uploads, "rounds": comm.rounds,
             "team_override": cfg.team, "oracle": cfg.acting().oracle,
             "privileged": cfg.acting().oracle}  # fmt: skip
    return type(f"LearnedTeam_{cfg.name}", (LearnedTeam,), attrs)
