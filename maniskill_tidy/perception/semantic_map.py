"""Top-down semantic maps from RGB-D + segmentation (the paper's Section 5.1 map).

Each frame's depth is back-projected into world points that carry a voxel label read off the
segmentation, with open3d's pinhole unprojection (camera intrinsics and pose): a numba kernel
repeats open3d's float32 arithmetic operation for operation, in row-major pixel order, at a
fifth of the call's cost (``tests/test_semantic_map.py`` checks it against open3d bit for bit
on rendered frames; ``bench --only map`` times both). Points are fused into a dense
voxel grid (``cell`` metres on every side, default 0.05 m) that keeps the latest label of
every voxel; the top-down map of shape (rows, cols, K + 2) is read off that grid:

- channel 0, obstacles: columns holding wall, furniture or object voxels between
  ``OBSTACLE_BAND`` heights (what blocks a robot; the floor does not);
- channel 1, explored: columns any back-projected point fell into, and cells whose floor a
  pixel sees (a z-buffer test: floor seen at a grazing angle counts as a whole, floor hidden
  behind furniture does not), and the cells the agent stands on;
- channel 2 + k, category k of ``Catalog.categories`` (every object and furniture type).

Surfaces seen at a grazing angle get one pixel row every 10-30 cm; points are filled in
between vertically adjacent pixels of one instance (:func:`densify`) so that a table top
seen from across the room is an obstacle and not floor-with-stripes.

Why a labelled voxel grid and not a TSDF: the renderer's depth has no noise to average away,
so a TSDF's weighted averaging buys no accuracy here, blurs labels at object boundaries, and
its integration plus the surface extraction a top-down read needs cost several times the
per-frame budget (``python -m maniskill_tidy.bench --only map`` times both on the same frames).
What a TSDF does give, free-space carving, matters for objects that move; the map gets it for
them by a visibility check: a stored object voxel that the current frame sees *through*
(its depth in the camera lies ``SEE_THROUGH`` in front of the measured depth), or whose pixel
shows something else at the voxel's own depth (the table a flat object lay on), is cleared.

Labels come from the ground-truth segmentation (instance id -> type), standing in for a
trained detector, as everywhere in this project's perception. Robots (dynamic obstacles)
and the object the agent holds are left out of the map.

The map frame is the house's navigation grid, subdivided: with 0.05 m cells five map cells
make one 0.25 m planner cell, so :meth:`SemanticMap.planner_grid` is an exact max-pool.

This module fuses frames; its per-point loops are numba kernels (``map_kernels.py``: numpy's
arithmetic, byte for byte); the grid and labels are ``map_grid.py``, what decisions read of a
map ``crops.py``, frontiers ``frontiers.py``, the ground truth ``map_truth.py``, a team's maps
``map_sharing.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from maniskill_tidy.houses.schema import House
from maniskill_tidy.knowledge import load_catalog
from maniskill_tidy.perception import map_kernels as kernels
from maniskill_tidy.perception.crops import (
    LabelRanks,
    egocentric_bits,
    egocentric_labels,
    pool_to_planner,
    wide_layout,
)
from maniskill_tidy.perception.frontiers import Frontier, find_frontiers
from maniskill_tidy.perception.map_grid import (
    EXPLORED,
    FIRST_CATEGORY,
    FIRST_CHANNEL,
    FLOOR_LABEL,
    OBSTACLE,
    OBSTACLE_BAND,
    UNKNOWN,
    WALL_LABEL,
    MapFrame,
    id_counts,
    label_table,
)

SEE_THROUGH = 0.1  # metres in front of the measured depth at which a stored voxel is gone
INTO_SURFACE = 0.005  # metres a hit is pushed along the optical axis, past float noise
FLOOR_HIT = 0.01  # metres: a pixel whose hit is lower sees the floor (not an obstacle's foot)
MIN_STEP = 0.03  # metres of depth between pixel rows below which the 3-D gap is under a cell
MAX_GAP = 0.5  # metres: wider gaps between neighbouring pixels of one instance are edges
ROBOT_FOOTPRINT = 0.2  # metres: the disc an agent stands on, known free without being seen


@dataclass(frozen=True)
class MapConfig:
    cell: float = 0.05  # metres, mapping resolution (x, y and z)
    height: float = 2.0  # metres of the voxel grid above the floor
    max_depth: float = 5.0  # metres; further pixels are left out (too few per cell to trust)
    stride: int = 1  # pixel stride of the back-projection
    crop_size: int = 20  # cells of the egocentric crop (the paper's G)
    crop_cell: float = 0.25  # metres per crop cell: the planner's grid

    def __post_init__(self) -> None:
        for name in ("cell", "height", "max_depth", "crop_cell"):
            if not getattr(self, name) > 0:
                raise ValueError(f"MapConfig.{name} must be > 0, got {getattr(self, name)!r}")
        if self.stride < 1 or self.crop_size < 1:
            raise ValueError(
                f"MapConfig.stride and crop_size must be >= 1, got {self.stride}, {self.crop_size}"
            )


@dataclass(frozen=True)
class FramePoints:
    """The last frame's back-projected pixels: world points, their segmentation ids and the
    camera's position. Detections and seen robots are read off these
    (``perception/detections.py``): the project's one back-projection path is the map's."""

    points: np.ndarray  # (N, 3)
    seg: np.ndarray  # (N,) segmentation id of each point's pixel
    camera: np.ndarray  # (3,) world position of the camera
    stride: int = 1  # pixel stride of the back-projection: a point stands for stride^2 pixels

    @cached_property
    def id_counts(self) -> tuple[np.ndarray, np.ndarray]:
        """The points' segmentation ids, ascending, and how many points carry each: counted
        once per frame, for the detections and the seen robots alike."""
        return id_counts(self.seg)


def camera_position(extrinsics) -> np.ndarray:
    """The camera's world position from its world-to-camera matrix: -R^T t."""
    ext = np.asarray(extrinsics, dtype=np.float64)
    return -ext[:3, :3].T @ ext[:3, 3]


def open3d_intrinsics(intrinsics) -> np.ndarray:
    """(fx, fy, cx, cy) in float32, as open3d's unprojection holds them. open3d puts pixel u at
    u, the renderer's model at u + 0.5: the principal point moves half a pixel first."""
    k = np.asarray(intrinsics, dtype=np.float64)
    return np.array([k[0, 0], k[1, 1], k[0, 2] - 0.5, k[1, 2] - 0.5], dtype=np.float32)


def open3d_pose(extrinsics) -> np.ndarray:
    """The 3 x 4 camera-to-world matrix as open3d's unprojection computes it from a
    world-to-camera matrix (``InverseTransformation``: R^T and -R^T t in float64, summed left
    to right) and holds it (float32)."""
    ext = np.asarray(extrinsics, dtype=np.float64)
    rotation = ext[:3, :3].T
    t = ext[:3, 3]
    shift = -(rotation[:, 0] * t[0] + rotation[:, 1] * t[1] + rotation[:, 2] * t[2])
    return np.concatenate([rotation, shift[:, None]], axis=1).astype(np.float32)


def backproject(depth: np.ndarray, label: np.ndarray, obs: dict, config: MapConfig):
    """Every ``config.stride``-th pixel with a depth as a world point: (points, segmentation
    ids) of all, and (points, labels, pixels) of those a map keeps, in row-major pixel order.
    ``depth`` is float32, ``label`` the pixels' voxel labels."""
    # A hit lies on a surface, often exactly on a cell boundary: it is pushed a little along
    # the optical axis so that it lands in the voxel of the surface it belongs to.
    all_points, point_seg, points, labels, pixels = kernels.backproject(
        label, depth, np.asarray(obs["segmentation"]), open3d_pose(obs["extrinsics"]),
        open3d_intrinsics(obs["intrinsics"]), np.float32(INTO_SURFACE),
        np.float32(config.max_depth), config.stride,
    )  # fmt: skip
    if not len(all_points):  # no depth in view: the empty arrays the map always had
        return np.zeros((0, 3)), point_seg, np.zeros((0, 3)), labels, np.zeros((0, 2), np.int64)
    return all_points, point_seg, points, labels, pixels


class SemanticMap:
    """One agent's fused map of one house (create a new one per house)."""

    def __init__(
        self,
        house: House,
        instances: dict,
        config: MapConfig | None = None,
        categories: tuple[str, ...] | None = None,
    ) -> None:
        self.config = config or MapConfig()
        catalog = load_catalog()
        self.categories = categories or catalog.categories
        if len(self.categories) + FIRST_CATEGORY > 255:
            raise ValueError(f"{len(self.categories)} categories do not fit uint8 voxel labels")
        self.frame = MapFrame.of_house(house, self.config.cell)
        self._origin = np.asarray(self.frame.origin, dtype=np.float64)  # for the kernels
        self.planner_shape = tuple(house.navgrid.shape)
        self.labels = label_table(instances, self.categories)
        small = set(catalog.pickupable)
        self._movable = np.zeros(256, dtype=bool)  # labels the visibility check may clear
        for i, name in enumerate(self.categories):
            self._movable[FIRST_CATEGORY + i] = name in small
        self._blocks = np.zeros(256, dtype=bool)  # labels that make obstacles: all but floor
        self._blocks[WALL_LABEL : FIRST_CATEGORY + len(self.categories)] = True
        rows, cols = self.frame.shape
        self.layers = int(math.ceil(self.config.height / self.config.cell))
        self.voxels = np.zeros((rows, cols, self.layers), dtype=np.uint8)
        self.explored = np.zeros((rows, cols), dtype=bool)
        self._movable_voxels = np.zeros(0, dtype=np.int64)  # flat indices, for the check
        self._top_down = np.zeros((rows, cols, self.channels), dtype=np.uint8)
        # the same channels as bits, 64 a word, for the crops (explored comes from its array)
        self._bits = np.zeros((rows, cols, (self.channels + 63) // 64), dtype=np.uint64)
        # the order of a label crop (map messages): small objects first
        self.label_ranks = LabelRanks(np.array([c in small for c in self.categories]))
        self._ranks = np.full((rows, cols), self.label_ranks.nothing, dtype=np.int16)
        self._band = (
            max(int(OBSTACLE_BAND[0] / self.config.cell), 0),
            int(math.ceil(OBSTACLE_BAND[1] / self.config.cell)),
        )
        self.frames = 0
        self._corner_rays: tuple = (None, None)  # (intrinsics and shape, camera-frame rays)
        self.last_frame = FramePoints(np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(3))

    @property
    def channels(self) -> int:
        return len(self.categories) + 2

    # ------------------------------------------------------------------ fusion
    def update(self, obs: dict) -> None:
        """Fuse one observation (``depth``, ``segmentation``, ``intrinsics``, ``extrinsics`` and
        optionally ``held``, the segmentation id of the agent's own held object)."""
        for key in ("depth", "segmentation", "intrinsics", "extrinsics"):
            if key not in obs:
                raise KeyError(
                    f"SemanticMap.update needs obs[{key!r}]; make the env with an obs_mode "
                    "that includes depth and segmentation"
                )
        depth = np.ascontiguousarray(obs["depth"], dtype=np.float32)
        seg = np.asarray(obs["segmentation"])
        held = int(obs.get("held", 0))
        label, labelled_depth, top = kernels.frame_labels(seg, depth, self.labels, held, UNKNOWN)
        if top >= len(self.labels):
            raise ValueError(
                f"segmentation id {int(top)} is not in this map's instance table "
                f"({len(self.labels)} ids): the map belongs to another house"
            )
        camera = camera_position(obs["extrinsics"])
        self._mark_visible_floor(
            depth, obs["intrinsics"], obs["extrinsics"], obs.get("pose"), camera
        )
        # Every pixel with a depth is back-projected once; robots, the held object and empty
        # space (label UNKNOWN) stay out of the map but are kept in ``last_frame``.
        all_points, point_seg, points, point_labels, pixels = backproject(
            depth, label, obs, self.config
        )
        self.last_frame = FramePoints(all_points, point_seg, camera, self.config.stride)
        depth = labelled_depth  # robots, the held object and empty space: no depth
        cleared = self._clear_seen_through(depth, label, obs["intrinsics"], obs["extrinsics"])
        extra, extra_labels = densify(
            points, point_labels, pixels, seg, depth, self.config.cell, self.config.stride
        )
        # a column re-read twice reads the same: no need to merge the two lists
        self._refresh_columns(self._fuse(points, point_labels, extra, extra_labels))
        if len(cleared):
            self._refresh_columns(cleared)
        self.frames += 1

    def _fuse(self, points, labels, extra, extra_labels) -> np.ndarray:
        """Write the points' labels into their voxels, the observed points first, then the
        filled-in ones; returns the flat column indices hit."""
        origin = np.array([*self.frame.origin, 0.0], dtype=np.float32)
        touched, moving = kernels.fuse_points(
            points, extra, labels, extra_labels, self.voxels, self.explored, self._movable,
            origin, np.float32(self.config.cell), FLOOR_LABEL,
        )  # fmt: skip
        if len(moving):
            self._movable_voxels = kernels.merge_unique(self._movable_voxels, moving)
        return touched

    def _mark_visible_floor(self, depth, intrinsics, extrinsics, pose, camera) -> None:
        """Explored: cells whose centre, on the floor, falls on a pixel that sees the floor.
        Floor seen at a grazing angle has a few pixels per cell and whole cells between pixel
        rows; this fills them without counting floor hidden behind furniture."""
        ext = np.asarray(extrinsics, dtype=np.float64)
        k = np.asarray(intrinsics, dtype=np.float64)
        reach = self.config.max_depth
        r0, r1, c0, c1 = self._view_window(camera, ext, k, depth.shape, reach)
        r, c, xyz = kernels.unexplored_cells(
            r0, r1, c0, c1, self.explored, self._origin, self.frame.cell
        )
        cam = xyz @ ext[:3, :3].T + ext[:3, 3]  # numpy's matmul: the kernels do no BLAS
        kernels.mark_floor_seen(
            cam, r, c, depth, k, ext, camera[2], reach, FLOOR_HIT, self.explored
        )
        if pose is not None:  # the agent stands there: known, though never in view
            kernels.mark_footprint(
                float(pose[0]), float(pose[1]), ROBOT_FOOTPRINT + self.config.cell,
                ROBOT_FOOTPRINT, self._origin, self.frame.cell, self.explored,
            )  # fmt: skip

    def _view_window(self, camera, ext, k, shape, reach) -> tuple[int, int, int, int]:
        """First and last rows and columns of the box around what the camera sees within ``reach``:
        the camera and the horizontal rays through the image's corners and centre."""
        key = (k.tobytes(), shape)
        if self._corner_rays[0] != key:  # a camera's own: made once, not every frame
            h, w = shape
            pixels = np.array([[0, 0], [w, 0], [0, h], [w, h], [w / 2, h / 2]], dtype=np.float64)
            self._corner_rays = key, np.column_stack(
                [(pixels[:, 0] - k[0, 2]) / k[0, 0], (pixels[:, 1] - k[1, 2]) / k[1, 1], np.ones(5)]
            )  # fmt: skip
        rays = self._corner_rays[1] @ ext[:3, :3]  # in world coordinates (rows of R^T applied)
        return kernels.view_window(
            camera, rays, reach, 2 * self.config.cell, self._origin, self.frame.cell,
            *self.frame.shape,
        )  # fmt: skip

    def _clear_seen_through(self, depth, label, intrinsics, extrinsics) -> np.ndarray:
        """Clear stored object voxels the camera now sees past, or sees something else right at
        (the object has moved); returns the flat column indices that changed."""
        flat = self._movable_voxels
        if len(flat) == 0:
            return np.zeros(0, dtype=np.int64)
        flat, world = kernels.object_voxel_centres(
            flat, self.voxels, self._movable, self._origin, self.frame.cell, self.config.cell,
        )  # fmt: skip
        ext = np.asarray(extrinsics, dtype=np.float64)
        cam = world @ ext[:3, :3].T + ext[:3, 3]  # numpy's matmul: the kernels do no BLAS
        # Not hidden behind something nearer, and either seen through by SEE_THROUGH or seen
        # to be another thing at its own depth (the table a flat object lay on).
        self._movable_voxels, cleared = kernels.clear_seen_through(
            flat, cam, depth, label, self.voxels, np.asarray(intrinsics, dtype=np.float64),
            self.config.cell, SEE_THROUGH, UNKNOWN,
        )  # fmt: skip
        return cleared

    def _refresh_columns(self, columns: np.ndarray) -> None:
        """Re-read the top-down channels of the (unique) columns whose voxels changed."""
        lo, hi = self._band
        kernels.refresh_columns(
            columns, self.voxels, self._top_down, self._bits, self._ranks, self.label_ranks.table,
            self._blocks, lo, hi, FIRST_CATEGORY, FIRST_CHANNEL, OBSTACLE,
            self.label_ranks.obstacle,
        )  # fmt: skip

    # ------------------------------------------------------------------ reading
    def top_down(self) -> np.ndarray:
        """(rows, cols, K + 2) uint8 0/1: obstacles, explored, one channel per category.
        A view of the map's own array: copy it to keep a snapshot."""
        self._top_down[..., EXPLORED] = self.explored
        return self._top_down

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres (N, 3) and labels (N,) of every occupied voxel: the fused point cloud."""
        r, c, z = np.nonzero(self.voxels)
        xyz = np.column_stack([self.frame.centres(r, c), (z + 0.5) * self.config.cell])
        return xyz, self.voxels[r, c, z]

    def planner_grid(self) -> np.ndarray:
        """The top-down map max-pooled onto the 0.25 m planner grid: (rows, cols, K + 2)."""
        return pool_to_planner(self.top_down(), self.planner_shape)

    def local_crop(self, pose, size: int | None = None, cell: float | None = None) -> np.ndarray:
        """The egocentric crop the scene encoder reads: :func:`egocentric_crop` of
        :meth:`top_down`, read off the map's bits (:func:`egocentric_bits`)."""
        return egocentric_bits(
            self._bits,
            self.explored,
            self.channels,
            self.frame,
            pose,
            size or self.config.crop_size,
            cell or self.config.crop_cell,
        )

    def label_crop(self, pose, size: int | None = None, cell: float | None = None) -> np.ndarray:
        """:meth:`local_crop` folded into one label per cell; see :func:`egocentric_labels`."""
        return egocentric_labels(
            self._ranks,
            self.explored,
            self.label_ranks,
            self.frame,
            pose,
            size or self.config.crop_size,
            cell or self.config.crop_cell,
        )

    def wide_layout(self, pose) -> np.ndarray:
        """The coarse egocentric view of the whole map; see :func:`wide_layout`."""
        return wide_layout(self.top_down(), self.frame, pose)

    def frontiers(self, min_cells: int = 5) -> list[Frontier]:
        return find_frontiers(self.top_down(), self.frame, min_cells)

    def frontier_targets(self, navgrid, min_cells: int = 5) -> list[tuple[int, int]]:
        """For an exploration policy: per frontier (largest first), the free planner cell
        nearest its centroid that the map does not show blocked; frontiers without one within
        a metre are skipped."""
        from maniskill_tidy.houses.navgrid import grid_array

        free = grid_array(navgrid) & ~self.planner_grid()[..., OBSTACLE].astype(bool)
        cells = np.argwhere(free)
        if len(cells) == 0:
            return []
        centres = np.column_stack(
            [
                navgrid.origin[0] + (cells[:, 1] + 0.5) * navgrid.cell,
                navgrid.origin[1] + (cells[:, 0] + 0.5) * navgrid.cell,
            ]
        )
        out = []
        for f in self.frontiers(min_cells):
            d = np.hypot(centres[:, 0] - f.centroid[0], centres[:, 1] - f.centroid[1])
            i = int(np.argmin(d))
            if d[i] <= 1.0 and tuple(cells[i]) not in out:
                out.append((int(cells[i, 0]), int(cells[i, 1])))
        return out


def densify(
    points: np.ndarray,
    labels: np.ndarray,
    pixels: np.ndarray,
    seg: np.ndarray,
    depth: np.ndarray,
    cell: float,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Points between vertically adjacent pixels on the same instance, one per cell of gap.

    A surface seen at a grazing angle (a table top from across the room) gets one pixel row
    every 10-30 cm; the cells between rows would read as explored (the floor under the table
    is visible) but free. Gaps wider than ``MAX_GAP`` are left alone: they cross an edge."""
    if len(points) == 0:
        return np.zeros((0, 3)), labels[:0]
    # A pixel and the one below it both hit one instance and their depths differ by more
    # than a neighbour's gap can without one (3.5 cm at 5 m), their points by over a cell.
    a, b, n = kernels.densify_pairs(
        pixels, stride, seg, depth, points,
        np.float32(cell), np.float32(MIN_STEP), np.float32(MAX_GAP),
    )  # fmt: skip
    return kernels.fill_gaps(points, labels, a, b, n)
