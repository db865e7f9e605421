"""What every learned agent does besides deciding: perceive its own frame, and carry out an
operation on what it sees.

:class:`PerceivingAgent` reads the agent's observation the way its training data was made
(``perception/frame_inputs.py``), runs the frozen perception model, keeps its own pose and
held object, and turns an operation (PickUp, PutDown, Drop) into an action with a target the
env accepts, or None when it cannot succeed from here. The paper's model (``learned.py``) and
QMIX (``qmix_team.py``) decide differently on top of it.
"""

from __future__ import annotations

import numpy as np
import torch

from maniskill_tidy.envs.actions import MIN_PIXELS, REACH, Action, AgentState, Targeted
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.perception.frame_inputs import FrameInputs, FrameReader
from maniskill_tidy.policies.base import Agent, AgentView, PublicInfo, SubTask
from maniskill_tidy.policies.channel import Outbox
from maniskill_tidy.policies.executor import SubGoalExecutor
from maniskill_tidy.policies.navigation import GridPlanner

MISPLACED = 0.5  # the detector's probability above which an object in reach is picked up
TOP_PUT = 3  # receptacle types (the likeliest) an object may be put down on


class PerceivingAgent(Agent):
    def __init__(
        self, name: str, public: PublicInfo, outbox: Outbox, perception,
        misplaced_detector: bool = True, wide: bool = False,
    ) -> None:  # fmt: skip
        super().__init__(name, public, outbox)
        self.perception = perception
        self.misplaced_detector = misplaced_detector
        self.i = public.agents.index(name)
        self.reader = FrameReader(public.house, public.instances, wide=wide)
        self.planner = GridPlanner(public.house)
        rng = np.random.default_rng([public.seed, self.i, 11])
        self.executor = SubGoalExecutor(self.planner, rng)
        self.capability = public.capability(name)
        self.state = AgentState(name, self.capability, (0, 0), 0)
        self.furniture = public.house.furniture_by_id()
        self.t = 0
        self._featured = False  # the perception model has run on this step's frame
        self._last_op: Action | None = None
        self.picked_from = -1  # receptacle type the held object was picked up from
        self.p_receptacle = np.zeros(len(load_catalog().receptacles))  # where to put it

    def perceive(self, view: AgentView) -> dict[str, torch.Tensor]:
        """Read the frame, update the agent's own state; the perception features (1, 1, ·)."""
        self.read(view)
        return self.features()

    def read(self, view: AgentView) -> None:
        """Read the frame into the map and update the agent's own state, without the frozen
        perception model (an agent that decides only at sub-goal steps runs it only then)."""
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
        self._featured = False

    def features(self) -> dict[str, torch.Tensor]:
        """The frozen perception model on this step's frame: the decision's inputs (1, 1, ·),
        and every detection's misplaced and receptacle probabilities."""
        f = self.frame
        with torch.inference_mode():  # no autograd bookkeeping at all: the same kernels
            feats = self.perception.step_features(
                torch.from_numpy(f.rgb[None]), torch.from_numpy(f.seen[None]),
                torch.from_numpy(f.crop[None]), torch.zeros(len(f.det_type), dtype=torch.long),
                torch.from_numpy(f.det_type), torch.from_numpy(f.det_rest),
                torch.from_numpy(f.det_numeric),
            )  # fmt: skip
        self._featured = True
        self.p_detections = feats["p_detections"].numpy()
        self.p_receptacles = feats["p_receptacles"].numpy()
        x = {k: feats[k][None] for k in ("sv", "sm", "fd", "fp", "mis", "det")}
        x.update(
            va=torch.tensor([[self.capability]], dtype=torch.float32),
            pose=torch.from_numpy(f.pose)[None, None],
            held=torch.tensor([[f.held]]),
            failed=torch.tensor([[float(self.failed)]]),
        )
        return x

    def _operation(self, ope: str, subtask: SubTask) -> Action | Targeted | None:
        """``ope`` on what is in view, or None when it cannot succeed from here."""
        # an operation that just failed here: look elsewhere before trying it again
        retry = self.failed and self._last_op in (Action.PickUp, Action.PutDown)
        if not self.capability[1] or retry:
            return None
        held = self.state.held is not None
        if ope == "PickUp" and not held:
            return self._pick(subtask)
        if ope == "PutDown" and held:
            return self._put(subtask)
        if ope == "Drop" and held:
            return Action.Drop
        return None

    def _pick(self, subtask: SubTask) -> Targeted | None:
        """The detected object in reach of the predicted type (else the likeliest misplaced),
        if the misplaced-object detector finds it misplaced (p >= MISPLACED)."""
        f: FrameInputs = self.frame
        if not self._featured:  # read without the model this step: its detections now
            self.features()
        here = np.asarray(self.public.house.navgrid.center(*self.state.cell))
        # without the detector (its ablation) any object in reach, the predicted type first
        gate = MISPLACED if self.misplaced_detector else -1.0
        near = [i for i in range(len(f.det_object))
                if np.hypot(*(f.det_position[i, :2] - here)) <= REACH
                and self.p_detections[i] >= gate]  # fmt: skip
        if not near:
            return None  # nothing misplaced in reach: not worth a failed action
        kind = load_catalog().categories
        same = [i for i in near if kind[f.det_type[i]] == subtask.object_type]
        best = max(same or near, key=lambda i: (self.p_detections[i] if gate > 0 else 0, -i))
        self.picked_from = int(f.det_rest[best])
        self.picked_receptacles = self.p_receptacles[best]  # the predictor's, for this object
        return Targeted(Action.PickUp, f.det_object[best])

    def _put(self, subtask: SubTask) -> Targeted | None:
        """The visible surface whose receptacle type ``p_receptacle`` finds likeliest, among its
        TOP_PUT likeliest types and not the type the object was picked up from; None if none is
        in view (the object is carried on)."""
        order = np.argsort(-self.p_receptacle)
        likely = [int(r) for r in order[:TOP_PUT] if int(r) != self.picked_from]
        rank = {load_catalog().receptacles[r]: k for k, r in enumerate(likely)}
        ids, counts = np.unique(self.seg, return_counts=True)
        best: tuple[int, str] | None = None
        for sid, n in zip(ids, counts, strict=True):
            inst = self.public.instances.get(int(sid))
            if inst is None or inst.kind != "furniture" or n < MIN_PIXELS:
                continue
            f = self.furniture.get(inst.id.split("/")[0])
            for surface in f.surfaces if f is not None else []:
                k = rank.get(surface.receptacle_type)
                if k is not None and (best is None or k < best[0]):
                    best = (k, f"{f.id}/{surface.name}")
        return Targeted(Action.PutDown, best[1]) if best is not None else None
