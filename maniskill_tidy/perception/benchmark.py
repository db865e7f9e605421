"""Map update cost per agent frame, next to the env step that produced the frame (same run).

Agents wander with random navigation actions; each step's three 224x224 frames go through
``SemanticMap.update`` (every pixel, and every other one: ``MapConfig(stride=2)``) and, for the
design comparison in ``semantic_map.py``, through an open3d
TSDF (``VoxelBlockGrid.integrate`` plus the point extraction a top-down read needs). The
map's back-projection kernel is timed against the open3d call it repeats bit for bit. Env step,
map updates and TSDF alternate frame by frame, so machine load hits all of them alike. The
learned team's per-frame reads of the map are timed too: the egocentric crop every agent reads,
and the wide layout only models with ``wide_layout`` read (``FrameReader(wide=...)``).
"""

from __future__ import annotations

import functools
import statistics
import time

import gymnasium as gym
import numpy as np
import open3d as o3d

from maniskill_tidy.envs.benchmark import NAV_ONLY
from maniskill_tidy.perception.map_sharing import TeamMaps
from maniskill_tidy.perception.semantic_map import INTO_SURFACE, MapConfig, backproject


@functools.cache
def _pixels(h: int, w: int) -> np.ndarray:
    """(h, w, 3) float32: each pixel's row and column (and row again), open3d's colour input."""
    rows, cols = np.mgrid[0:h, 0:w]
    return np.ascontiguousarray(np.stack([rows, cols, rows], axis=-1), dtype=np.float32)


def open3d_cloud(depth: np.ndarray, obs: dict, config: MapConfig) -> tuple:
    """open3d's own back-projection of a frame, as the map called it before its kernel: the
    points (N, 3) float32 and their pixels (N, 2), in the order open3d's parallel loop emits
    them (it varies between calls). Each point carries its pixel through as a colour."""
    h, w = depth.shape
    k = np.asarray(obs["intrinsics"], dtype=np.float64).copy()
    k[0, 2] -= 0.5  # open3d puts pixel u at u, the renderer's model at u + 0.5
    k[1, 2] -= 0.5
    pushed = np.where(depth > 0, depth + np.float32(INTO_SURFACE), np.float32(0))
    cloud = o3d.t.geometry.PointCloud.create_from_rgbd_image(
        o3d.t.geometry.RGBDImage(o3d.t.geometry.Image(_pixels(h, w)), o3d.t.geometry.Image(pushed)),
        o3d.core.Tensor(k),
        o3d.core.Tensor(np.asarray(obs["extrinsics"], dtype=np.float64)),
        depth_scale=1.0,
        depth_max=config.max_depth,
        stride=config.stride,
    )
    if cloud.is_empty():
        return np.zeros((0, 3), np.float32), np.zeros((0, 2), np.int64)
    return cloud.point.positions.numpy(), cloud.point.colors.numpy()[:, :2].astype(np.int64)


def open3d_backprojection(depth: np.ndarray, label: np.ndarray, obs: dict, config: MapConfig):
    """``semantic_map.backproject`` through open3d itself, the kernel's reference: the same
    five arrays, open3d's points put back in row-major pixel order."""
    points, at = open3d_cloud(depth, obs, config)
    seg = np.asarray(obs["segmentation"])
    if not len(points):
        empty = np.zeros((0, 3)), seg[:0, 0], np.zeros((0, 3)), np.zeros(0, np.uint8)
        return (*empty, np.zeros((0, 2), np.int64))
    order = np.argsort(at[:, 0] * depth.shape[1] + at[:, 1])
    points, at = points[order], at[order]
    kept = label[at[:, 0], at[:, 1]] != 0
    labels = label[at[:, 0], at[:, 1]][kept].astype(np.uint8)
    return points, seg[at[:, 0], at[:, 1]], points[kept], labels, at[kept]


class TSDFMap:
    """The alternative the map design was measured against (not used by the project)."""

    def __init__(self, config: MapConfig) -> None:
        self.config = config
        self.grid = o3d.t.geometry.VoxelBlockGrid(
            attr_names=("tsdf", "weight", "color"),  # colour carries the label, as in the map
            attr_dtypes=(o3d.core.float32, o3d.core.float32, o3d.core.float32),
            attr_channels=((1), (1), (3)),
            voxel_size=config.cell,
            block_resolution=8,
            block_count=20000,
        )

    def update(self, obs: dict) -> None:
        depth = o3d.t.geometry.Image(np.ascontiguousarray(obs["depth"], dtype=np.float32))
        k = o3d.core.Tensor(np.asarray(obs["intrinsics"], dtype=np.float64))
        ext = o3d.core.Tensor(np.asarray(obs["extrinsics"], dtype=np.float64))
        blocks = self.grid.compute_unique_block_coordinates(
            depth, k, ext, 1.0, self.config.max_depth
        )
        seg = np.asarray(obs["segmentation"], dtype=np.float32)
        label = o3d.t.geometry.Image(np.ascontiguousarray(np.repeat(seg[..., None], 3, axis=2)))
        self.grid.integrate(blocks, depth, label, k, ext, 1.0, self.config.max_depth)

    def read(self) -> np.ndarray:
        return self.grid.extract_point_cloud(weight_threshold=1.0).point.positions.numpy()


def bench_map(steps: int = 40, seed: int = 0) -> dict:
    env = gym.make("HeteroTidy-v1", obs_mode="rgb+depth+segmentation", setting="I")
    u = env.unwrapped
    rng = np.random.default_rng(seed)
    try:
        obs, _ = env.reset(seed=seed, options={"episode": 0})
        config = MapConfig()
        maps = TeamMaps(u.house, u.instances, u.agent_names, config)
        strided = TeamMaps(u.house, u.instances, u.agent_names, MapConfig(stride=2))
        tsdf = {name: TSDFMap(config) for name in u.agent_names}
        env_ms, map_ms, stride_ms, tsdf_ms, crop_ms, wide_ms = [], [], [], [], [], []
        kernel_ms, o3d_ms = [], []
        for _ in range(steps):
            start = time.perf_counter()
            obs, *_ = env.step({n: int(rng.choice(NAV_ONLY)) for n in u.agent_names})
            env_ms.append((time.perf_counter() - start) * 1e3 / len(u.agent_names))
            for name, m in maps.maps.items():
                start = time.perf_counter()
                m.update(obs[name])
                m.top_down()
                map_ms.append((time.perf_counter() - start) * 1e3)
                pose = np.asarray(obs[name]["pose"], dtype=np.float32)[:3]
                start = time.perf_counter()
                m.local_crop(pose)
                crop_ms.append((time.perf_counter() - start) * 1e3)
                start = time.perf_counter()
                m.wide_layout(pose)
                wide_ms.append((time.perf_counter() - start) * 1e3)
                start = time.perf_counter()
                strided.maps[name].update(obs[name])
                strided.maps[name].top_down()
                stride_ms.append((time.perf_counter() - start) * 1e3)
                depth = np.ascontiguousarray(obs[name]["depth"], dtype=np.float32)
                label = m.labels[np.asarray(obs[name]["segmentation"])]
                config = strided.maps[name].config
                start = time.perf_counter()
                backproject(depth, label, obs[name], config)
                kernel_ms.append((time.perf_counter() - start) * 1e3)
                start = time.perf_counter()
                open3d_cloud(depth, obs[name], config)  # the call alone, its points unordered
                o3d_ms.append((time.perf_counter() - start) * 1e3)
                start = time.perf_counter()
                tsdf[name].update(obs[name])
                tsdf[name].read()
                tsdf_ms.append((time.perf_counter() - start) * 1e3)
    finally:
        env.close()
    h, w = u.camera_size
    return {
        "frames": len(map_ms),
        "size": f"{w}x{h}",
        "env_ms": statistics.median(env_ms),
        "map_ms": statistics.median(map_ms),
        "stride2_ms": statistics.median(stride_ms),
        "tsdf_ms": statistics.median(tsdf_ms),
        "crop_ms": statistics.median(crop_ms),
        "wide_ms": statistics.median(wide_ms),
        "kernel_ms": statistics.median(kernel_ms),
        "open3d_ms": statistics.median(o3d_ms),
        "map_per_env": statistics.median(map_ms) / statistics.median(env_ms),
    }


def report(r: dict) -> str:
    return (
        f"semantic map update per agent frame ({r['size']}, {r['frames']} frames, medians;\n"
        "env step cost shared out per agent frame; map = update + top-down read)\n"
        f"{'env ms':>7} {'map ms':>7} {'map/env':>8} {'stride 2 ms':>12} {'TSDF ms':>8}\n"
        f"{r['env_ms']:>7.2f} {r['map_ms']:>7.2f} {r['map_per_env']:>8.2f} "
        f"{r['stride2_ms']:>12.2f} {r['tsdf_ms']:>8.2f}\n"
        "learned inputs read off the map per agent frame (medians)\n"
        f"{'crop ms':>8} {'wide ms':>8} {'wide/env':>9}\n"
        f"{r['crop_ms']:>8.2f} {r['wide_ms']:>8.2f} {r['wide_ms'] / r['env_ms']:>9.2f}\n"
        "back-projection at stride 2 (medians): the map's kernel (points labelled, in pixel\n"
        "order) and the open3d call it repeats bit for bit (its points in any order)\n"
        f"{'kernel ms':>10} {'open3d ms':>10} {'ratio':>6}\n"
        f"{r['kernel_ms']:>10.2f} {r['open3d_ms']:>10.2f} {r['open3d_ms'] / r['kernel_ms']:>6.1f}"
    )
