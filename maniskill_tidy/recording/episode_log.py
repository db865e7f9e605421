"""One rerun recording per episode, on a ``step`` timeline.

Entity paths:

- ``world/house/{walls,furniture}``: static boxes; ``world/objects``: every object as a labelled
  box, misplaced ones red until they rest somewhere reasonable (then green);
- ``world/agents/<name>``: the robot's pose; ``world/cameras/<name>``: its camera (pinhole, so
  the viewer draws the frustum) with ``rgb``, ``depth`` and ``segmentation`` images; the
  segmentation's class legend (instance id -> "type id") is an annotation context on
  ``world/cameras``;
- ``agents/<name>/{action,failed,held,subtask}``: text logs per step;
- ``comm/messages`` (text), ``comm/matrix`` (values sent this step, sender x receiver),
  ``comm/groups`` (a graph: agents and who talked to whom this step; for a team whose agents
  report handshake groups (HanGrCom), those groups, with the value links as edges),
  ``comm/values`` (scalar); ``comm/T`` (HanGrCom's communication matrix, receiver x sender)
  and ``agents/<name>/attention`` (its row of T);
- ``metrics/{reasonable,picked,comm_per_agent_step}``: scalars over time;
- with images (depth and segmentation) in the observations, each agent's semantic map
  (``perception/semantic_map.py``): ``maps/<name>`` and the merged ``maps/team`` as class
  images (north up; hover for the category), and the fused voxels as points in the 3D view,
  ``world/maps/<name>`` (floor left out), every ``POINTS_EVERY`` steps and at the end.

The file is written to a temporary name and renamed when the episode ends, so a recording on
disk is always complete.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from maniskill_tidy.envs.actions import Action, Targeted
from maniskill_tidy.sim.appearance import hashed_colour

APP_ID = "maniskill_tidy"
POINTS_EVERY = 25  # steps between logs of the fused point clouds (they are large)
MISPLACED, TIDIED, OTHER = (230, 40, 40), (40, 200, 70), (150, 150, 150)


def recording_path(directory: Path, episode_id: str) -> Path:
    return Path(directory) / (episode_id.replace("/", "__") + ".rrd")


def layout(agents: list[str], maps: bool = False) -> rrb.Blueprint:
    """The viewer's opening layout: house in 3D, each agent's camera (and map), communication,
    metrics."""
    cameras = [
        rrb.Spatial2DView(
            origin=f"world/cameras/{a}",
            name=a,
            contents=[f"world/cameras/{a}/rgb", f"world/cameras/{a}/segmentation"],
        )
        for a in agents
    ]
    left = [rrb.Spatial3DView(origin="world", name="house"), rrb.Horizontal(*cameras)]
    if maps:
        left.append(
            rrb.Horizontal(
                *[rrb.Spatial2DView(origin=f"maps/{a}", name=f"{a} map") for a in agents],
                rrb.Spatial2DView(origin="maps/team", name="team map (merged)"),
            )
        )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(*left, row_shares=[3, 2, 2][: len(left)]),
            rrb.Vertical(
                rrb.GraphView(origin="comm/groups", name="communication groups"),
                rrb.TensorView(origin="comm/matrix", name="values sent (sender x receiver)"),
                rrb.TimeSeriesView(origin="metrics", name="metrics"),
                rrb.TextLogView(origin="/", name="actions, failures, messages"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _yaw_quat(yaw: float) -> list[float]:
    return [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]  # xyzw


class EpisodeRecorder:
    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)

    # ------------------------------------------------------------------ episode
    def start(self, env, team, channel) -> None:
        self.env, self.channel = env, channel
        self.directory.mkdir(parents=True, exist_ok=True)
        self.path = recording_path(self.directory, env.episode.id)
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self.rec = rr.RecordingStream(APP_ID, recording_id=env.episode.id)
        self.rec.save(str(self.tmp))
        obs = env.get_obs()
        first = next(iter(obs.values()), {})
        self.maps = None
        if "depth" in first and "segmentation" in first:
            from maniskill_tidy.perception.map_sharing import TeamMaps

            self.maps = TeamMaps(env.house, env.instances, [a.name for a in env.agents])
        self.rec.send_blueprint(layout([a.name for a in env.agents], self.maps is not None))
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._log_house()
        self._log_legend()
        if self.maps is not None:
            self._log_map_legend()
        self.rec.log(
            "episode",
            rr.TextDocument(
                f"episode {env.episode.id} ({env.episode.task.kind}, k={len(env.misplaced)}), "
                f"team {team.name}: " + ", ".join(f"{a.name} {a.capability}" for a in env.agents)
            ),
            static=True,
        )
        self.log_step(0, obs, {}, env.get_info(), channel, {})

    def log_step(self, t: int, obs: dict, actions: dict, info: dict, channel, labels) -> None:
        rec, env = self.rec, self.env
        rec.set_time("step", sequence=t)
        self._log_objects(info)
        for a in env.agents:
            o = obs[a.name]
            x, y, rot = (float(v) for v in o["pose"])
            rec.log(
                f"world/agents/{a.name}",
                rr.Transform3D(translation=[x, y, 0.0], quaternion=_yaw_quat(math.radians(rot))),
                rr.Boxes3D(
                    half_sizes=[[0.18, 0.18, 0.05]], labels=[a.name], colors=[hashed_colour(a.name)]
                ),
            )
            cam_to_world = np.linalg.inv(o["extrinsics"])
            h, w = (o["rgb"].shape[:2]) if "rgb" in o else (224, 224)
            base = f"world/cameras/{a.name}"
            rec.log(
                base, rr.Transform3D(translation=cam_to_world[:3, 3], mat3x3=cam_to_world[:3, :3])
            )
            rec.log(
                base,
                rr.Pinhole(
                    image_from_camera=o["intrinsics"],
                    resolution=[w, h],
                    camera_xyz=rr.ViewCoordinates.RDF,
                    image_plane_distance=0.4,
                ),
            )
            if not a.stopped:  # a stopped agent's camera is off (its last images stay shown)
                if "rgb" in o:
                    rec.log(f"{base}/rgb", rr.Image(o["rgb"]))
                if "depth" in o:
                    rec.log(f"{base}/depth", rr.DepthImage(o["depth"], meter=1.0))
                if "segmentation" in o:
                    rec.log(f"{base}/segmentation", rr.SegmentationImage(o["segmentation"]))
            if a.name in actions:
                act = actions[a.name]
                text = (
                    f"{Action(act.action).name} {act.target}"
                    if isinstance(act, Targeted)
                    else Action(int(act)).name
                )
                rec.log(f"agents/{a.name}/action", rr.TextLog(text))
            reason = info.get("failed", {}).get(a.name)
            if reason:
                rec.log(f"agents/{a.name}/failed", rr.TextLog(reason, level=rr.TextLogLevel.WARN))
            rec.log(f"agents/{a.name}/held", rr.TextLog(a.held or "-"))
            if a.name in labels:
                subtask, subgoal = labels[a.name]
                rec.log(f"agents/{a.name}/subtask", rr.TextLog(f"{subtask} {subgoal}"))
        self._log_comm(channel)
        if self.maps is not None:
            self.maps.update({a.name: obs[a.name] for a in env.agents if not a.stopped})
            self._log_maps(points=t % POINTS_EVERY == 0)
        n = max(len(env.agents), 1)
        rec.log("metrics/reasonable", rr.Scalars(float(info.get("n_reasonable", 0))))
        rec.log("metrics/picked", rr.Scalars(float(len(info.get("picked", [])))))
        rec.log("metrics/comm_per_agent_step", rr.Scalars(channel.total / (max(t, 1) * n)))

    def traced(self, t: int, traces: dict) -> None:
        """HanGrCom's T and groups, decided at step ``t`` (shown with that step's messages), and
        the object-memory pointer's choices of job."""
        self._handshake = None
        for name, tr in traces.items():
            if "job" in tr:
                self.rec.set_time("step", sequence=t + 1)
                text = f"{tr['job']} (p {tr['p']:.2f} of {tr['candidates']} candidates)"
                self.rec.log(f"agents/{name}/choice", rr.TextLog(text))
        reported = [tr for tr in traces.values() if "T" in tr]
        if not reported:
            return
        self.rec.set_time("step", sequence=t + 1)
        names = [a.name for a in self.env.agents]
        for name, tr in traces.items():
            if "T" in tr:
                self.rec.log(f"agents/{name}/attention", rr.BarChart(tr["T"][names.index(name)]))
        first = reported[0]
        self.rec.log("comm/T", rr.Tensor(first["T"], dim_names=["receiver i", "sender j"]))
        self._handshake = (first["groups"], first.get("links", []))

    def finish(self, record) -> Path:
        self.rec.set_time("step", sequence=record.length)
        if self.maps is not None:
            self._log_maps(points=True)
        self.rec.log("episode/result", rr.TextLog(str(record.to_dict())))
        self.rec.flush()
        self.rec.disconnect()
        self.tmp.replace(self.path)
        return self.path

    # ------------------------------------------------------------------ pieces
    def _log_house(self) -> None:
        house, rec = self.env.house, self.rec
        centres, halves, quats = [], [], []
        for wall in house.walls:
            (x0, y0), (x1, y1) = wall.start, wall.end
            centres.append([(x0 + x1) / 2, (y0 + y1) / 2, wall.height / 2])
            halves.append([math.hypot(x1 - x0, y1 - y0) / 2, wall.thickness / 2, wall.height / 2])
            quats.append(_yaw_quat(math.atan2(y1 - y0, x1 - x0)))
        rec.log(
            "world/house/walls",
            rr.Boxes3D(
                centers=centres, half_sizes=halves, quaternions=quats, colors=[(200, 200, 190)]
            ),
            static=True,
        )
        f = house.furniture
        rec.log(
            "world/house/furniture",
            rr.Boxes3D(
                centers=[[o.position[0], o.position[1], o.position[2] + o.size[2] / 2] for o in f],
                half_sizes=[[s / 2 for s in o.size] for o in f],
                quaternions=[_yaw_quat(o.yaw) for o in f],
                labels=[o.id for o in f],
                colors=[hashed_colour(o.type) for o in f],
            ),
            static=True,
        )

    def _log_legend(self) -> None:
        infos = [rr.AnnotationInfo(id=0, label="empty", color=(0, 0, 0))]
        for sid, inst in sorted(self.env.instances.items()):
            infos.append(
                rr.AnnotationInfo(
                    id=int(sid),
                    label=f"{inst.kind}: {inst.type} {inst.id}",
                    color=hashed_colour(inst.id),
                )
            )
        self.rec.log("world/cameras", rr.AnnotationContext(infos), static=True)

    def _log_map_legend(self) -> None:
        from maniskill_tidy.perception.map_figure import class_legend

        categories = next(iter(self.maps.maps.values())).categories
        context = rr.AnnotationContext(
            [
                rr.AnnotationInfo(id=i, label=label, color=c)
                for i, label, c in class_legend(categories)
            ]
        )
        self.rec.log("maps", context, static=True)
        self.rec.log("world/maps", context, static=True)

    def _log_maps(self, points: bool) -> None:
        """Class images of every agent's map and the team's; the fused voxels if ``points``
        (voxel labels double as class ids: 2 wall, 3 + k category k; floor voxels left out)."""
        from maniskill_tidy.perception.map_figure import map_classes
        from maniskill_tidy.perception.map_grid import WALL_LABEL

        rec = self.rec
        for name, m in self.maps.maps.items():
            rec.log(
                f"maps/{name}", rr.SegmentationImage(map_classes(m.top_down(), m.categories)[::-1])
            )
            if points:
                xyz, labels = m.points()
                keep = labels >= WALL_LABEL
                rec.log(
                    f"world/maps/{name}",
                    rr.Points3D(xyz[keep], class_ids=labels[keep], radii=m.config.cell / 2),
                )
        rec.log(
            "maps/team", rr.SegmentationImage(map_classes(self.maps.merged(), m.categories)[::-1])
        )

    def _log_objects(self, info: dict) -> None:
        env = self.env
        misplaced, ok = set(env.misplaced), set(info.get("reasonable", []))
        centres, halves, labels, colours = [], [], [], []
        for oid, size in env.manipulation.sizes.items():
            bottom = env.hs.object_bottom(oid)
            centres.append([bottom[0], bottom[1], bottom[2] + size[2] / 2])
            halves.append([s / 2 for s in size])
            labels.append(oid)
            colours.append(TIDIED if oid in ok else MISPLACED if oid in misplaced else OTHER)
        self.rec.log(
            "world/objects",
            rr.Boxes3D(centers=centres, half_sizes=halves, labels=labels, colors=colours),
        )

    def _log_comm(self, channel) -> None:
        rec = self.rec
        for m in channel.step_messages:
            rec.log("comm/messages", rr.TextLog(f"{m.sender} -> {m.receiver}: {m.kind} ({m.dims})"))
        rec.log("comm/matrix", rr.Tensor(channel.matrix(), dim_names=["sender", "receiver"]))
        rec.log("comm/values", rr.Scalars(float(channel.step_total)))
        ids = channel.endpoints
        handshake = getattr(self, "_handshake", None)
        if handshake is not None:  # the groups the agents formed, not all traffic
            groups, links = handshake
            group_of = {a: f"{a} (group {k})" for k, g in enumerate(groups) for a in g}
            labels = [group_of.get(a, a) for a in ids]
            rec.log("comm/groups", rr.GraphNodes(node_ids=ids, labels=labels))
            rec.log("comm/groups", rr.GraphEdges(edges=sorted(links), graph_type="directed"))
            return
        rec.log("comm/groups", rr.GraphNodes(node_ids=ids, labels=ids))
        edges = sorted({(m.sender, m.receiver) for m in channel.step_messages})
        rec.log("comm/groups", rr.GraphEdges(edges=edges or [], graph_type="directed"))
