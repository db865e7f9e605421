"""HeteroTidy-v1/-v2: a heterogeneous robot team tidies up a multi-room house (the paper's task).

The two versions are two looks of one task (``visuals``): v1 draws flat-coloured primitives, v2
the derived meshes and materials of ``sim/realistic.py`` and hides, per camera, the rooms it
cannot see (``hide_unseen_rooms``; same pixels, less to rasterize).

A ManiSkill3 ``BaseEnv``: ``_load_scene`` builds the episode's house (only when the house
changes) and the team's robots, ``_initialize_episode`` lays out the task's misplaced objects and
the start poses, ``evaluate`` judges every misplaced object with D(o, p, r). Actions are a
``Dict`` of per-agent ``Discrete`` spaces with the rules of ``envs/actions.py``.

The simulation runs on the CPU, one house per env (houses differ per episode), so ``num_envs``
is 1 and, as gymnasium's single-env API (and ManiSkill's ``CPUGymWrapper``) expect,
observations are NumPy arrays without a batch dimension. Per agent they hold:

- ``rgb`` (H, W, 3) uint8; ``depth`` (H, W) float32 metres along the optical axis, 0 where
  nothing was hit; ``segmentation`` (H, W) int32 instance ids (``env.instances`` maps them to
  kind, type and id; 0 is empty space);
- ``pose`` (x, y, rotation in degrees), ``intrinsics`` (3, 3) and ``extrinsics`` (4, 4, world
  to OpenCV camera), ``capability`` (Nav, Mani, Hei), ``held`` (segmentation id of the held
  object, 0 if none).

An agent that has stopped takes no more pictures: its camera is off, and its observation keeps
the images of the step before it stopped (the other entries stay current). Nobody reads them (a
team sees only its active agents' views), and an expert's demonstration has two of its three
agents stopped in about half of its steps.

``obs_mode`` picks the images as in ManiSkill ("rgb+depth+segmentation", "rgb", "depth", any
``+`` combination, or "none"). With "none" no camera renders on a normal step, which is what
policies that ignore images (the privileged expert, Random) want: PickUp and PutDown still judge
visibility on a segmentation, rendered on demand for the acting agent at the start of the step,
i.e. of the same scene state an observation at the end of the previous step would have shown.
"""

from __future__ import annotations

import dataclasses
import gc
import math
from collections import Counter
from functools import cached_property

import cv2
import gymnasium as gym
import numpy as np
import sapien
from gymnasium.utils import seeding
from mani_skill.envs.sapien_env import BaseEnv
from mani_skill.render.shaders import PREBUILT_SHADER_CONFIGS, ShaderConfig
from mani_skill.sensors.camera import CameraConfig
from mani_skill.utils.registration import register_env

from maniskill_tidy.envs.actions import (
    HORIZON_RANGE,
    LOOK,
    MAX_STEPS,
    NOTHING_DRAWN,
    TARGETS,
    TURN,
    Action,
    AgentState,
    Pixel,
    move_target,
    parse_action,
)
from maniskill_tidy.envs.episodes import Episode, EpisodeSet
from maniskill_tidy.envs.manipulation import Manipulation
from maniskill_tidy.envs.registration import ENV_ID, register_gym
from maniskill_tidy.envs.robots import build_robot, robot_kind, robot_pose
from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import FLOOR, load_placement
from maniskill_tidy.sim import SHADERS, brdf_lut
from maniskill_tidy.sim.house_scene import HouseScene, Instance
from maniskill_tidy.sim.visibility import camera_arc
from maniskill_tidy.tasks.metatask import apply_task
from maniskill_tidy.tasks.teams import setting_team

QUALITIES = ("fast", "high")
LOOKS = ("flat", "realistic")  # HeteroTidy-v1, HeteroTidy-v2
SEG_MAX = 2**15 - 1  # the render shader writes instance ids as int16
FAR = 30.0  # metres, camera far plane
LIMIT = 1e4  # bound of poses (m) and camera matrices in the observation space


def pixel_counts(seg: np.ndarray) -> Counter:
    """Pixels per instance id of a segmentation image."""
    return Counter(dict(zip(*np.unique(seg, return_counts=True), strict=True)))


def default_render_backend() -> str:
    """ "gpu" when SAPIEN finds a CUDA device to render with, else the CPU (lavapipe) backend."""
    try:
        sapien.Device("cuda")
        return "gpu"
    except RuntimeError:
        return "cpu"


gym.registry.pop(ENV_ID, None)  # the lazy entry from maniskill/__init__; register_env adds it


# Envs made and not yet closed in this process: the heap stays frozen (see __init__) while
# any of them is open.
_open_envs = 0


# the picture formats ManiSkill gives SAPIEN's "minimal" pack (mani_skill/render/shaders.py),
# which v1's own pack of it needs too
MINIMAL_FORMATS = {
    "Color": "r8g8b8a8unorm",
    "ColorRaw": "r8g8b8a8unorm",
    "PositionSegmentation": "r16g16b16a16sint",
}


@register_env(ENV_ID, max_episode_steps=None)
class HeteroTidyEnv(BaseEnv):
    SUPPORTED_OBS_MODES = ("rgb+depth+segmentation", "any_textures", "none")
    SUPPORTED_REWARD_MODES = ("dense", "sparse", "none")
    metadata = {"render_modes": ["rgb_array", "sensors", "all"], "render_fps": 5}

    def __init__(
        self,
        *args,
        setting: str | list = "I",
        dataset: str | None = None,
        split: str = "train",
        task_type: str = "all",
        episode: int | str | None = None,
        camera_size: tuple[int, int] = (224, 224),
        camera_fov: float = 90.0,
        quality: str = "fast",
        visuals: str = "flat",
        hide_unseen_rooms: bool | None = None,
        render_size: tuple[int, int] = (640, 480),
        max_steps: int = MAX_STEPS,
        targets: str = "ids",
        **kwargs,
    ) -> None:
        if quality not in QUALITIES:
            raise ValueError(f"quality {quality!r} is not one of {QUALITIES}")
        if visuals not in LOOKS:
            raise ValueError(f"visuals {visuals!r} is not one of {LOOKS}")
        if kwargs.get("num_envs", 1) != 1:
            raise ValueError("HeteroTidy-v1 simulates one house per env: num_envs must be 1")
        if targets not in TARGETS:
            raise ValueError(f"targets={targets!r}: expected one of {TARGETS}")
        self.targets = targets  # "pixels": Targeted actions name pixels, never ids
        self.setting, self.team = setting_team(setting)
        self.agent_names = [f"agent_{i}" for i in range(len(self.team))]
        self.kinds = [robot_kind(c) for c in self.team]
        self.episodes = EpisodeSet(dataset, split, task_type, self.setting, self.team)
        self.fixed_episode = episode
        self.camera_size, self.camera_fov = tuple(camera_size), float(camera_fov)
        self.render_size, self.max_steps = tuple(render_size), int(max_steps)
        self.quality, self.visuals = quality, visuals
        # v2 "fast" hides, per camera, the rooms it cannot see (sim/visibility.py): the same
        # pixels, less geometry for the software rasterizer. Not with shadows ("high"): the
        # shadow pass would miss what hidden pieces cast into the room in view. v1 renders
        # everything, as it always did.
        default_hide = visuals == "realistic" and quality == "fast"
        self.hide_unseen_rooms = default_hide if hide_unseen_rooms is None else hide_unseen_rooms
        self.knowledge = load_placement()
        self.hs: HouseScene | None = None
        self._episode: Episode | None = None
        self._last_seg: dict[str, np.ndarray] = {}
        self._pictures: dict[str, dict[str, np.ndarray]] = {}  # each agent's last, read
        self._segmentation_cameras: dict[str, sapien.render.RenderCameraComponent] = {}
        kwargs.setdefault("render_backend", default_render_backend())
        kwargs.setdefault("obs_mode", "rgb+depth+segmentation")
        kwargs["robot_uids"] = "none"
        kwargs["enable_shadow"] = quality == "high"
        super().__init__(*args, **kwargs)
        self.action_space = gym.spaces.Dict(
            {
                n: gym.spaces.Discrete(s.n_actions)
                for n, s in zip(self.agent_names, self.agents, strict=True)
            }
        )
        self.single_action_space = self.action_space
        # ManiSkill collects all garbage at every reconfigure, here every episode (see reset),
        # and a full collection walked everything the process had loaded (the episodes, the
        # libraries): a reset took 0.27 s, now 0.07 (v1, `bench --only looks`). What exists
        # now lives as long as the env, so it is frozen out of those collections and each
        # walks only what was made since; the last env of the process to close thaws it.
        global _open_envs
        gc.collect()
        gc.freeze()
        _open_envs += 1
        self._holds_freeze = True

    def close(self) -> None:
        global _open_envs
        try:
            super().close()
        finally:
            if getattr(self, "_holds_freeze", False):  # close() may be called more than once
                self._holds_freeze = False
                _open_envs -= 1
                if _open_envs == 0:
                    gc.unfreeze()

    # ------------------------------------------------------------------ spaces
    @cached_property
    def single_observation_space(self) -> gym.spaces.Dict:
        return self.observation_space

    @cached_property
    def observation_space(self) -> gym.spaces.Dict:
        h, w = self.camera_size[1], self.camera_size[0]
        visual = self.obs_mode_struct.visual
        per_agent = {}
        if visual.rgb:
            per_agent["rgb"] = gym.spaces.Box(0, 255, (h, w, 3), np.uint8)
        if visual.depth:
            per_agent["depth"] = gym.spaces.Box(0.0, FAR, (h, w), np.float32)
        if visual.segmentation:
            per_agent["segmentation"] = gym.spaces.Box(0, SEG_MAX, (h, w), np.int32)
        per_agent |= {
            "pose": gym.spaces.Box(
                np.array([-LIMIT, -LIMIT, 0.0], np.float32),
                np.array([LIMIT, LIMIT, 360.0], np.float32),
            ),
            "intrinsics": gym.spaces.Box(-LIMIT, LIMIT, (3, 3), np.float32),
            "extrinsics": gym.spaces.Box(-LIMIT, LIMIT, (4, 4), np.float32),
            "capability": gym.spaces.MultiBinary(3),
            "held": gym.spaces.Box(0, SEG_MAX, (), np.int32),
        }
        return gym.spaces.Dict({n: gym.spaces.Dict(per_agent) for n in self.agent_names})

    # ------------------------------------------------------------------ scene
    def _load_scene(self, options: dict) -> None:
        house = self.episodes.houses[self._episode.house_id]
        self.hs = HouseScene(
            self.scene,
            house,
            shadows=self.quality == "high",
            realistic=self.visuals == "realistic",
        )
        self.manipulation = Manipulation(self.hs)
        self.robot_actors, self.robots = [], []
        for name, kind in zip(self.agent_names, self.kinds, strict=True):
            actor = build_robot(self.scene, name, kind, realistic=self.visuals == "realistic")
            entity = actor._objs[0]
            self.robot_actors.append(actor)
            self.robots.append(entity)
            self.hs.instances[entity.per_scene_id] = Instance(
                entity.per_scene_id, "robot", kind.name, name
            )
        self.hs.build_ceilings()  # v2 only; after the robots, so every other id is v1's

    def _load_lighting(self, options: dict) -> None:
        """Lights come with the house (``HouseScene``)."""

    def _setup_sensors(self, options: dict) -> None:
        for texture, fmt in MINIMAL_FORMATS.items():  # ManiSkill sets them for "minimal" only
            sapien.render.set_picture_format(texture, fmt)
        super()._setup_sensors(options)
        if self.visuals == "flat" and any(s.render_system.cubemap for s in self.scene.sub_scenes):
            raise RuntimeError("v1's cameras drop image-based light, but the scene has a cube map")
        self._segmentation_cameras = {}  # made on demand, on this scene's robots
        if self.backend.render_device.is_cpu():
            # lavapipe: SAPIEN's own BRDF table would cost 5-6 s at the process's first
            # picture (docs/research/probes/startup_probe.py); the cached one draws the same pixels
            # (sim/brdf_lut.py)
            cameras = [*self._sensors.values(), *self._human_render_cameras.values()]
            brdf_lut.lend(c for cam in cameras for c in cam.camera._render_cameras)

    @property
    def _default_sensor_configs(self) -> list[CameraConfig]:
        w, h = self.camera_size
        return [
            CameraConfig(
                uid=name,
                pose=sapien.Pose(p=[kind.camera_ahead, 0.0, kind.camera_height]),
                width=w,
                height=h,
                fov=math.radians(self.camera_fov),
                near=0.02,
                far=FAR,
                mount=actor,
                shader_config=self._camera_shader,
            )
            for name, kind, actor in zip(
                self.agent_names, self.kinds, self.robot_actors, strict=True
            )
        ]

    @property
    def _camera_shader(self) -> ShaderConfig:
        """The agents' cameras' shaders: SAPIEN's minimal pack, or in v1 the same pack without
        image-based lighting (``sim/shaders/no_ibl``). v1 sets no environment map, so SAPIEN's
        cube map is black and that light adds exactly zero: the same pixels, a sixth sooner on
        lavapipe (``docs/research/probes/shader_cost.py``)."""
        minimal = PREBUILT_SHADER_CONFIGS["minimal"]
        if self.visuals != "flat":
            return minimal
        return dataclasses.replace(minimal, shader_pack=str(SHADERS / "no_ibl"))

    @property
    def _default_human_render_camera_configs(self) -> CameraConfig:
        house = self.hs.house
        xs = [p[0] for r in house.rooms for p in r.polygon]
        ys = [p[1] for r in house.rooms for p in r.polygon]
        cx, cy = (min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2
        fov = math.radians(50)
        aspect = self.render_size[0] / self.render_size[1]
        span = max((max(xs) - min(xs)) / aspect, max(ys) - min(ys))
        dist = span / 2 / math.tan(fov / 2) * 1.15 + 2.0
        pitch = math.radians(62)
        eye = [cx, cy - dist * math.cos(pitch), dist * math.sin(pitch)]
        q = sapien.Pose(q=[math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]) * sapien.Pose(
            q=[math.cos(pitch / 2), 0, math.sin(pitch / 2), 0]
        )
        return CameraConfig(
            "third_person",
            pose=sapien.Pose(p=eye, q=q.q),
            width=self.render_size[0],
            height=self.render_size[1],
            fov=fov,
            near=0.1,
            far=100.0,
        )

    def get_state_dict(self) -> dict:
        return self.scene.get_sim_state()

    # ------------------------------------------------------------------ episodes
    def reset(self, seed=None, options=None):
        """``options``: ``episode`` (index or id) to play a given episode, else one is drawn
        from the split with the seeded episode RNG (the same seed gives the same episode)."""
        options = dict(options or {})
        if seed is not None:
            first = seed[0] if np.iterable(seed) else seed
            self._np_random, self._np_random_seed = seeding.np_random(int(first))
        key = options.get("episode", self.fixed_episode)
        if key is None:
            key = int(self.np_random.integers(len(self.episodes)))
        self._episode = self.episodes.get(key)
        # Rebuild the scene every episode (0.07 s in v1, 0.12 s in v2): PhysX keeps
        # contact and sleep state between episodes of one house, so reusing the scene let an
        # episode's settled poses depend, by micrometres, on the episodes played before it in
        # the same process.
        options["reconfigure"] = True
        obs, info = super().reset(seed=seed, options=options)
        return obs, self._plain_info(info)

    def _initialize_episode(self, env_idx, options: dict) -> None:
        ep = self._episode
        messy = apply_task(self.hs.house, ep.task)
        self.hs.place_objects(messy)
        self.fallen = self.hs.settle()
        self.agents = [
            AgentState(name, cap, tuple(s["cell"]), int(s["rotation"]))
            for name, cap, s in zip(self.agent_names, self.team, ep.starts, strict=True)
        ]
        self.misplaced = [m.object for m in ep.task.misplaced]
        self.picked: set[str] = set()
        self._pictures = {}
        self._t = 0
        self._solved_before = self._reasonable()
        for i in range(len(self.agents)):
            self._place_robot(i)

    def _place_robot(self, i: int) -> None:
        a, kind = self.agents[i], self.kinds[i]
        x, y = self.hs.house.navgrid.center(*a.cell)
        pose = robot_pose(x, y, a.rotation)
        self.robots[i].set_pose(pose)
        pitch = math.radians(a.horizon)
        local = sapien.Pose(
            p=[kind.camera_ahead, 0.0, kind.camera_height],
            q=[math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0],
        )
        self._agent_camera(a.name).set_local_pose(local)
        if a.name in self._segmentation_cameras:
            self._segmentation_cameras[a.name].set_local_pose(local)
        self.manipulation.carry(a, pose, kind.hold_offset)

    @property
    def instances(self) -> dict[int, Instance]:
        """Segmentation id -> what it shows (kind, type, id), for the current house."""
        return self.hs.instances

    @property
    def house(self) -> House:
        return self.hs.house

    @property
    def episode(self) -> Episode:
        return self._episode

    # ------------------------------------------------------------------ stepping
    def step(self, action):
        actions = self._check_actions(action)
        if not self._renders_every_step:
            self._last_seg.update(
                self._render_segmentations(
                    [n for n, (act, _) in actions.items() if act in (Action.PickUp, Action.PutDown)]
                )
            )
        failed: dict[str, str] = {}
        for i, a in enumerate(self.agents):
            if a.stopped:
                continue
            act, target = actions[a.name]
            a.steps += 1
            reason = self._apply(i, act, target)
            failed[a.name] = reason or ""
            if reason:
                a.failures.append(reason)
        self._t += 1
        self._elapsed_steps += 1
        info = self.get_info()
        info["failed"] = failed
        obs = self.get_obs(info)
        reward = self._reward(info)
        terminated = all(a.stopped for a in self.agents)
        truncated = self._t >= self.max_steps and not terminated
        return obs, reward, terminated, truncated, info

    def _check_actions(self, action) -> dict[str, tuple[Action, str | Pixel | None]]:
        if not isinstance(action, dict):
            raise TypeError(
                f"actions must be a dict agent name -> action, got {type(action).__name__}"
            )
        unknown = sorted(set(action) - set(self.agent_names))
        if unknown:
            raise KeyError(f"unknown agents {unknown}; this team has {self.agent_names}")
        missing = [a.name for a in self.agents if not a.stopped and a.name not in action]
        if missing:
            raise KeyError(f"no action for {missing}; every agent that has not stopped needs one")
        return {
            name: parse_action(
                value, self.agents[self.agent_names.index(name)].n_actions, name, self.targets
            )
            for name, value in action.items()
        }

    def _apply(self, i: int, act: Action, target: str | Pixel | None) -> str | None:
        a = self.agents[i]
        if act in (Action.MoveAhead, Action.MoveRight, Action.MoveLeft):
            cell = move_target(a, act)
            if not self.hs.house.navgrid.free(*cell):
                return f"{act.name} blocked by a wall or furniture"
            other = next((b.name for b in self.agents if b is not a and b.cell == cell), None)
            if other:
                return f"{act.name} blocked by {other}"
            a.cell = cell
        elif act in (Action.RotateRight, Action.RotateLeft):
            a.rotation = (a.rotation + (-TURN if act == Action.RotateRight else TURN)) % 360
        elif act in (Action.LookUp, Action.LookDown):
            horizon = a.horizon + (-LOOK if act == Action.LookUp else LOOK)
            if not HORIZON_RANGE[0] <= horizon <= HORIZON_RANGE[1]:
                return f"{act.name} beyond the camera's range {HORIZON_RANGE} degrees"
            a.horizon = horizon
        elif act == Action.Stop:
            a.stopped = True
            return None
        else:
            return self._manipulate(i, act, target)
        self._place_robot(i)
        return None

    def _manipulate(self, i: int, act: Action, target: str | Pixel | None) -> str | None:
        a = self.agents[i]
        xy = np.asarray(self.hs.house.navgrid.center(*a.cell))
        seg = self._last_seg.get(a.name)
        counts = Counter() if seg is None else pixel_counts(seg)
        aim = None
        if isinstance(target, tuple):
            aim = target
            target, reason = self._pixel_target(act, seg, target)
            if reason:
                return reason
        if act == Action.PickUp:
            reason = self.manipulation.pick_up(a, xy, counts, target)
            if reason is None:
                if a.held in self.misplaced:
                    self.picked.add(a.held)
                self._place_robot(i)
            return reason
        if act == Action.PutDown:
            camera = self._camera_matrices(a.name)
            return self.manipulation.put_down(a, xy, counts, camera, target, aim)
        return self.manipulation.drop(a)

    def _pixel_target(self, act: Action, seg, pixel: Pixel) -> tuple[str | None, str | None]:
        """The id drawn at a pixel of the agent's current frame: an object for PickUp, a piece
        of furniture (or its door or drawer) for PutDown; or why there is none."""
        x, y = pixel
        h, w = self.camera_size[1], self.camera_size[0]
        if not (0 <= x < w and 0 <= y < h):
            return None, f"{act.name} at pixel {pixel}: outside the {w} x {h} frame"
        sid = int(np.asarray(seg).reshape(h, w)[y, x]) if seg is not None else 0
        inst = self.hs.instances.get(sid)
        want = "object" if act == Action.PickUp else "furniture"
        if inst is None or inst.kind != want:
            return None, f"{act.name} at pixel {pixel}: no {want} {NOTHING_DRAWN}"
        # a door or drawer is part of its piece: PutDown tries the piece's surfaces nearest the
        # pixel first (Manipulation.put_candidates)
        return (inst.id if want == "object" else inst.id.split("/")[0]), None

    def preview(
        self, name: str, cell: tuple[int, int], rotation: int, horizon: int
    ) -> tuple[Counter, tuple]:
        """Privileged query (for the expert): what ``name``'s camera would see from a pose.

        Returns the segmentation's pixel count per instance id and the camera (intrinsic,
        extrinsic, width, height) as PickUp and PutDown use them. Nothing in the episode changes:
        the robot is put back where it stands.
        """
        i = self.agent_names.index(name)
        a = self.agents[i]
        saved = a.cell, a.rotation, a.horizon
        a.cell, a.rotation, a.horizon = cell, rotation, horizon
        self._place_robot(i)
        counts = pixel_counts(self._render_segmentations([name])[name])
        camera = self._camera_matrices(name)
        a.cell, a.rotation, a.horizon = saved
        self._place_robot(i)
        return counts, camera

    # ------------------------------------------------------------------ task state
    def is_reasonable(self, oid: str) -> bool:
        """D where the object rests now (held, on the floor or nowhere known: not reasonable)."""
        st = self.hs.state[oid]
        if st.receptacle in ("held", "unknown", FLOOR):
            return False
        f = self.hs.furniture[st.receptacle]
        rtype = f.surface(st.surface).receptacle_type
        return self.knowledge.D(self.manipulation.types[oid], rtype, self.hs.room_type[f.room])

    def _reasonable(self) -> list[str]:
        return [oid for oid in self.misplaced if self.is_reasonable(oid)]

    def evaluate(self) -> dict:
        reasonable = self._reasonable()
        return {
            "success": len(reasonable) == len(self.misplaced),
            "reasonable": reasonable,
            "n_reasonable": len(reasonable),
            "n_misplaced": len(self.misplaced),
            "picked": sorted(self.picked),
            "steps": {a.name: a.steps for a in self.agents},
            "held": {a.name: a.held for a in self.agents},
            "stopped": {a.name: a.stopped for a in self.agents},
        }

    def get_info(self) -> dict:
        return self._plain_info(super().get_info())

    def _plain_info(self, info: dict) -> dict:
        info = dict(info)
        info["elapsed_steps"] = self._t
        info["episode"] = self._episode.id
        info["task_kind"] = self._episode.task.kind
        info.setdefault("failed", {})
        if "reconfigure" in info:
            info["reconfigure"] = bool(info["reconfigure"])
        info["fallen"] = list(getattr(self, "fallen", []))
        return info

    def _reward(self, info: dict) -> float:
        if self._reward_mode == "none":
            return 0.0
        now = info["n_reasonable"]
        before, self._solved_before = len(self._solved_before), info["reasonable"]
        if self._reward_mode == "sparse":
            return float(info["success"] and before < now)
        return float(now - before)

    def render(self):
        """The third-person view (``render_mode="rgb_array"``) as an (H, W, 3) uint8 array; it
        looks down into the house, so v2's ceilings are hidden while it renders."""
        self.hs.set_ceilings_visible(False)
        try:
            image = super().render()
        finally:
            self.hs.set_ceilings_visible(True)
        if image is None:
            return None
        image = image.cpu().numpy() if hasattr(image, "cpu") else np.asarray(image)
        return image[0] if image.ndim == 4 else image

    # ------------------------------------------------------------------ observations
    @property
    def _renders_every_step(self) -> bool:
        visual = self.obs_mode_struct.visual
        return bool(visual.rgb or visual.depth or visual.segmentation)

    def _render_segmentations(self, names: list[str]) -> dict[str, np.ndarray]:
        """Fresh segmentations of ``names``' cameras, without the other images."""
        if not names:
            return {}
        cameras = {name: self._segmentation_camera(name) for name in names}  # before the update
        self.scene.update_render(update_sensors=True, update_human_render_cameras=False)
        self._take_pictures(cameras)
        return {
            name: cam.get_picture("PositionSegmentation")[..., 3].astype(np.int32)
            for name, cam in cameras.items()
        }

    def _segmentation_camera(self, name: str) -> sapien.render.RenderCameraComponent:
        """A camera on ``name``'s mount with its own camera's parameters, whose shader writes
        the segmentation alone (``sim/shaders/segmentation``: the same vertex stage and the same
        discarded fragments, no lighting). The expert's previews and the PickUp / PutDown checks
        without pictures read nothing else; the ids are the agent camera's, pixel for pixel
        (tests/test_env.py)."""
        cam = self._segmentation_cameras.get(name)
        if cam is None:
            config = self._sensor_configs[name]
            cam = sapien.render.RenderCameraComponent(
                config.width, config.height, str(SHADERS / "segmentation")
            )
            cam.set_fovy(config.fov, compute_x=True)  # as ManiSkill makes the agent's camera
            cam.near, cam.far = config.near, config.far
            self.robots[self.agent_names.index(name)].add_component(cam)
            own = self._agent_camera(name)
            cam.set_local_pose(own.get_local_pose())  # pitched with it (_place_robot)
            self._segmentation_cameras[name] = cam
        return cam

    def _take_pictures(self, cameras: dict[str, sapien.render.RenderCameraComponent]) -> None:
        """Each agent's camera (``cameras``, by agent) renders with the rooms it cannot see
        hidden (if ``hide_unseen_rooms``); everything is shown again afterwards (the
        third-person view draws the whole house)."""
        groups = None
        if self.hide_unseen_rooms:
            movers = dict(self.hs.objects) | dict(zip(self.agent_names, self.robots, strict=True))
            groups = self.hs.room_groups(movers)
        try:
            for name, cam in cameras.items():
                if groups is not None:
                    self.hs.show_rooms(groups, self.visible_rooms(name))
                cam.take_picture()
        finally:
            if groups is not None:
                self.hs.show_rooms(groups, None)

    def _agent_camera(self, name: str) -> sapien.render.RenderCameraComponent:
        """The SAPIEN camera behind ManiSkill's sensor ``name``."""
        return self._sensors[name].camera._render_cameras[0]

    def visible_rooms(self, name: str) -> set[str]:
        """The rooms ``name``'s camera may see from where it is (floor plan and doorways)."""
        a = self.agents[self.agent_names.index(name)]
        kind = self.kinds[self.agent_names.index(name)]
        x, y = self.hs.house.navgrid.center(*a.cell)
        yaw = math.radians(a.rotation)
        xy = (x + kind.camera_ahead * math.cos(yaw), y + kind.camera_ahead * math.sin(yaw))
        w, h = self.camera_size
        view = camera_arc(yaw, math.radians(a.horizon), math.radians(self.camera_fov), w / h)
        return self.hs.plan.visible_rooms(xy, view)

    def _camera_matrices(self, name: str) -> tuple[np.ndarray, np.ndarray, int, int]:
        """(intrinsic, extrinsic, width, height) as PickUp and PutDown use them."""
        cam = self._agent_camera(name)
        return cam.get_intrinsic_matrix(), cam.get_extrinsic_matrix(), cam.width, cam.height

    def get_obs(self, info: dict | None = None, unflattened: bool = False) -> dict:
        render = self._renders_every_step
        if render:
            # a stopped agent's camera is off once it has pictures to keep
            live = [a.name for a in self.agents if not a.stopped or a.name not in self._pictures]
            self.scene.update_render(update_sensors=True, update_human_render_cameras=False)
            self._take_pictures({n: self._agent_camera(n) for n in live})
        obs = {}
        for i, a in enumerate(self.agents):
            cam = self._agent_camera(a.name)
            o = {}
            if render and a.name in live:
                o = self._read_pictures(a.name)
                self._pictures[a.name] = {k: v.copy() for k, v in o.items()}
            elif render:  # its camera is off: copies of its last pictures, kept apart from
                # the arrays handed out (SAPIEN warns on every read of a camera not taken)
                o = {k: v.copy() for k, v in self._pictures[a.name].items()}
            x, y = self.hs.house.navgrid.center(*a.cell)
            extrinsic = np.eye(4, dtype=np.float32)
            extrinsic[:3] = cam.get_extrinsic_matrix()
            held = self.manipulation.seg_of_object[a.held] if a.held else 0
            o = o | {
                "pose": np.array([x, y, a.rotation], dtype=np.float32),
                "intrinsics": cam.get_intrinsic_matrix().astype(np.float32),
                "extrinsics": extrinsic,
                "capability": np.array(self.team[i], dtype=np.int8),
                "held": np.array(held, dtype=np.int32),
            }
            obs[a.name] = o
        return obs

    def _read_pictures(self, name: str) -> dict[str, np.ndarray]:
        """``name``'s pictures, once its camera has been taken; its segmentation is kept for
        PickUp and PutDown."""
        visual = self.obs_mode_struct.visual
        cam = self._agent_camera(name)
        o = {}
        if visual.rgb:
            # alpha dropped by OpenCV: numpy's copy of the strided view cost 0.45 ms a
            # camera (docs/research/probes/profile_team.py hangrcom --callers ascontiguousarray)
            o["rgb"] = cv2.cvtColor(cam.get_picture("Color"), cv2.COLOR_RGBA2RGB)
        pos = cam.get_picture("PositionSegmentation")
        seg = pos[..., 3].astype(np.int32)
        self._last_seg[name] = seg
        if visual.depth:
            o["depth"] = pos[..., 2].astype(np.float32) * np.float32(-1e-3)
        if visual.segmentation:
            o["segmentation"] = seg
        return o


# ManiSkill's register_env also registers with gymnasium, adding its own time-limit wrapper
# that replaces ``truncated`` with a torch tensor; this env truncates itself and returns NumPy.
register_gym()
