"""The semantic map's per-point loops, compiled with numba (issue 48).

Each kernel does in one pass what ``semantic_map.py`` did with a dozen numpy calls over the
frame's ~12,000 points, whose overhead, not their arithmetic, was most of the map's cost (the
map was two thirds of a heuristic team's thinking). They release Python's lock, so the agents
of a team fuse their frames on threads side by side.

Every kernel repeats numpy's arithmetic operation for operation, in the same precision and
order (float32 where the numpy code worked in float32, numpy's promotion rules where it mixed),
with no fast-math: the map is byte for byte what the numpy code made
(``docs/research/probes/map_update_ab.py`` compares both on recorded frames), so no record changes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# ``cache=True`` keeps the machine code beside the module (or in numba's user cache where the
# package directory is read-only): a process compiles each kernel once, ever.
_jit = njit(cache=True, nogil=True)


@_jit
def pixel_of(k, x, y, z):
    """The pixel (u, v) a camera-frame point in front of the camera (z > 0) falls on."""
    u = np.int64(np.floor(k[0, 0] * x / z + k[0, 2]))
    v = np.int64(np.floor(k[1, 1] * y / z + k[1, 2]))
    return u, v


@_jit
def frame_labels(seg, depth, table, held, unknown):
    """Each pixel's voxel label (``table[seg]``; ``unknown`` on the held object's pixels) and
    the depth where it is labelled (0 elsewhere), in one pass. Returns them and the largest
    id in ``seg``: an id beyond the table is not looked up, and the caller refuses the frame."""
    h, w = seg.shape
    label = np.empty((h, w), np.uint8)
    labelled = np.empty((h, w), np.float32)
    top = 0
    for r in range(h):
        for c in range(w):
            s = seg[r, c]
            top = max(top, s)
            lab = table[s] if s < len(table) and not (held != 0 and s == held) else unknown
            label[r, c] = lab
            labelled[r, c] = depth[r, c] if lab != unknown else np.float32(0)
    return label, labelled, top


@_jit
def view_window(camera, rays, reach, pad, origin, cell, rows, cols):
    """First and last rows and columns of the box around the camera and the ends of the
    horizontal ``rays`` (world directions) at ``reach``, ``pad`` wider on every side and
    clipped to the map (numpy's float64 arithmetic of ``SemanticMap._view_window``)."""
    lo_x = hi_x = camera[0]
    lo_y = hi_y = camera[1]
    for i in range(len(rays)):
        norm = max(np.sqrt(rays[i, 0] * rays[i, 0] + rays[i, 1] * rays[i, 1]), 1e-9)
        x = camera[0] + reach * (rays[i, 0] / norm)
        y = camera[1] + reach * (rays[i, 1] / norm)
        lo_x, hi_x = min(lo_x, x), max(hi_x, x)
        lo_y, hi_y = min(lo_y, y), max(hi_y, y)
    r0 = np.int64(np.floor((lo_y - pad - origin[1]) / cell))
    r1 = np.int64(np.floor((hi_y + pad - origin[1]) / cell))
    c0 = np.int64(np.floor((lo_x - pad - origin[0]) / cell))
    c1 = np.int64(np.floor((hi_x + pad - origin[0]) / cell))
    r0, r1 = min(max(r0, 0), rows), min(max(r1, 0), rows)
    return r0, r1, min(max(c0, 0), cols), min(max(c1, 0), cols)


@_jit
def mark_footprint(x, y, pad, radius, origin, cell, explored):
    """Mark explored the cells whose centre lies within ``radius`` of (x, y), among those of
    the box ``pad`` around it (clipped to the map, as numpy clipped it)."""
    rows, cols = explored.shape
    r0 = min(max(np.int64(np.floor((y - pad - origin[1]) / cell)), 0), rows - 1)
    r1 = min(max(np.int64(np.floor((y + pad - origin[1]) / cell)), 0), rows - 1)
    c0 = min(max(np.int64(np.floor((x - pad - origin[0]) / cell)), 0), cols - 1)
    c1 = min(max(np.int64(np.floor((x + pad - origin[0]) / cell)), 0), cols - 1)
    for r in range(r0, r1 + 1):
        cy = origin[1] + (r + 0.5) * cell
        for c in range(c0, c1 + 1):
            if np.hypot(origin[0] + (c + 0.5) * cell - x, cy - y) <= radius:
                explored[r, c] = True


@_jit
def backproject(label, depth, seg, pose, intrinsics, into_surface, depth_max, stride):
    """Every ``stride``-th pixel with a depth as a world point, in row-major pixel order.

    open3d's pinhole unprojection (``t.geometry.PointCloud.create_from_rgbd_image``, CPU)
    operation for operation in its float32: ``intrinsics`` is (fx, fy, cx, cy) and ``pose``
    the 3 x 4 camera-to-world matrix, both float32 as open3d holds them, the depth first pushed
    ``into_surface`` along the optical axis. Returns every point and its segmentation id (for
    ``last_frame``), and the points, labels and pixels of those the map keeps: label 0
    (UNKNOWN: robots, the held object) is not mapped."""
    h, w = depth.shape
    n = (h // stride) * (w // stride)
    fx, fy, cx, cy = intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3]
    points = np.empty((n, 3), np.float32)
    point_seg = np.empty(n, seg.dtype)
    mapped = np.empty((n, 3), np.float32)
    mapped_pixels = np.empty((n, 2), np.int64)
    mapped_labels = np.empty(n, np.uint8)
    k = m = 0
    for r in range(0, (h // stride) * stride, stride):
        v = np.float32(r)
        for c in range(0, (w // stride) * stride, stride):
            d = depth[r, c]
            if not d > 0:
                continue
            d = d + into_surface
            if not (d > 0 and d < depth_max):
                continue
            x = (np.float32(c) - cx) * d / fx
            y = (v - cy) * d / fy
            for a in range(3):
                points[k, a] = x * pose[a, 0] + y * pose[a, 1] + d * pose[a, 2] + pose[a, 3]
            point_seg[k] = seg[r, c]
            if label[r, c] != 0:
                mapped[m] = points[k]
                mapped_pixels[m, 0], mapped_pixels[m, 1] = r, c
                mapped_labels[m] = label[r, c]
                m += 1
            k += 1
    return points[:k], point_seg[:k], mapped[:m], mapped_labels[:m], mapped_pixels[:m]


@_jit
def densify_pairs(pixels, stride, seg, depth, points, cell, min_step, max_gap):
    """Vertically adjacent pixels (a above b) of every ``stride``-th row and column, of one
    instance, whose 3-D gap needs filling: their point indices (``pixels`` holds each point's)
    and the number of segments of the gap, in row-major order of a. ``cell``, ``min_step`` and
    ``max_gap`` are float32, as numpy compared them."""
    h, w = seg.shape
    rows, cols = (h + stride - 1) // stride, (w + stride - 1) // stride
    index = np.full((rows, cols), -1, np.int64)  # the point at each strided pixel
    for i in range(len(pixels)):
        index[pixels[i, 0] // stride, pixels[i, 1] // stride] = i
    a_out = np.empty(rows * cols, np.int64)
    b_out = np.empty(rows * cols, np.int64)
    n_out = np.empty(rows * cols, np.int64)
    k = 0
    for r in range(rows - 1):
        for c in range(cols):
            a, b = index[r, c], index[r + 1, c]
            above, below = r * stride, (r + 1) * stride
            if a < 0 or b < 0 or seg[above, c * stride] != seg[below, c * stride]:
                continue
            if not abs(depth[above, c * stride] - depth[below, c * stride]) > min_step:
                continue
            dx = points[a, 0] - points[b, 0]
            dy = points[a, 1] - points[b, 1]
            dz = points[a, 2] - points[b, 2]
            gap = np.sqrt(dx * dx + dy * dy + dz * dz)  # float32, as np.linalg.norm
            if gap > cell and gap < max_gap:
                a_out[k], b_out[k] = a, b
                n_out[k] = np.int64(np.ceil(gap / cell))
                k += 1
    return a_out[:k], b_out[:k], n_out[:k]


@_jit
def fill_gaps(points, labels, a, b, n):
    """The n - 1 points inside each gap a -> b (float64: numpy promoted t * (b - a) so)."""
    total = 0
    for i in range(len(n)):
        total += n[i] - 1
    extra = np.empty((total, 3), np.float64)
    extra_labels = np.empty(total, labels.dtype)
    k = 0
    for i in range(len(n)):
        pa, pb = points[a[i]], points[b[i]]
        for j in range(1, n[i]):
            t = j / n[i]
            for d in range(3):
                extra[k, d] = np.float64(pa[d]) + t * np.float64(pb[d] - pa[d])
            extra_labels[k] = labels[a[i]]
            k += 1
    return extra, extra_labels


@_jit
def fuse_points(points, extra, labels, extra_labels, voxels, explored, movable, origin, cell,
                floor_label):  # fmt: skip
    """Write each point's label into its voxel, in order (the last write wins): the observed
    points, then the filled-in ones. Marks their columns explored; returns the sorted columns
    hit and the flat indices of the movable-object voxels written."""
    rows, cols, layers = voxels.shape
    hit = np.zeros(rows * cols, np.bool_)
    moving = np.empty(len(points) + len(extra), np.int64)
    m = 0
    flat_voxels = voxels.reshape(-1)
    flat_explored = explored.reshape(-1)
    for i in range(len(points) + len(extra)):
        if i < len(points):
            p0, p1, p2, label = points[i, 0], points[i, 1], points[i, 2], labels[i]
        else:
            j = i - len(points)
            p0 = np.float32(extra[j, 0])
            p1 = np.float32(extra[j, 1])
            p2 = np.float32(extra[j, 2])
            label = extra_labels[j]
        x = np.int32(np.floor((p0 - origin[0]) / cell))
        y = np.int32(np.floor((p1 - origin[1]) / cell))
        z = np.int32(np.floor((p2 - origin[2]) / cell))
        if z == -1 and label == floor_label:
            z = 0  # the floor's rendered surface
        if x < 0 or x >= cols or y < 0 or y >= rows:
            continue
        column = np.int64(y) * cols + x
        flat_explored[column] = True
        hit[column] = True
        if z < 0 or z >= layers:
            continue
        flat = column * layers + z
        flat_voxels[flat] = label
        if movable[label]:
            moving[m] = flat
            m += 1
    return np.flatnonzero(hit), moving[:m]


@_jit
def object_voxel_centres(flat, voxels, movable, origin, cell, z_cell):
    """Of the voxels ``flat`` (flat indices), those that still hold a movable object, and their
    centres in world coordinates (``MapFrame.centres`` and the layer's middle, float64)."""
    rows, cols, layers = voxels.shape
    flat_voxels = voxels.reshape(-1)
    still = np.empty(len(flat), np.int64)
    world = np.empty((len(flat), 3), np.float64)
    n = 0
    for i in range(len(flat)):
        f = flat[i]
        if not movable[flat_voxels[f]]:
            continue
        r, rest = f // (cols * layers), f % (cols * layers)
        c, z = rest // layers, rest % layers
        still[n] = f
        world[n, 0] = origin[0] + (c + 0.5) * cell
        world[n, 1] = origin[1] + (r + 0.5) * cell
        world[n, 2] = (z + 0.5) * z_cell
        n += 1
    return still[:n], world[:n]


@_jit
def merge_unique(sorted_unique, more):
    """``np.union1d(sorted_unique, more)`` for an ascending array without repeats: ``more``
    is sorted and merged in, one pass instead of sorting both again (issue 48)."""
    more = np.sort(more)
    out = np.empty(len(sorted_unique) + len(more), sorted_unique.dtype)
    i = j = n = 0
    while i < len(sorted_unique) or j < len(more):
        if j == len(more) or (i < len(sorted_unique) and sorted_unique[i] <= more[j]):
            v = sorted_unique[i]
            i += 1
        else:
            v = more[j]
            j += 1
        if n == 0 or out[n - 1] != v:
            out[n] = v
            n += 1
    return out[:n]


@_jit
def clear_seen_through(flat, cam, depth, label, voxels, k, cell, see_through, unknown):
    """Clear the object voxels ``flat`` (centres ``cam`` in camera coordinates) that the frame
    shows something else at, or sees past by ``see_through``, unless something nearer hides
    them; returns the voxels kept and the flat columns of those cleared
    (``SemanticMap._clear_seen_through``'s float64 tests)."""
    h, w = depth.shape
    layers = voxels.shape[-1]
    flat_voxels = voxels.reshape(-1)
    kept = np.empty(len(flat), np.int64)
    cleared = np.empty(len(flat), np.int64)
    n_kept = n_cleared = 0
    for i in range(len(flat)):
        z = cam[i, 2]
        gone = False
        if z > 1e-6:  # in front of the camera
            u, v = pixel_of(k, cam[i, 0], cam[i, 1], z)
            if 0 <= u < w and 0 <= v < h:
                measured = np.float64(depth[v, u])
                other = label[v, u] != flat_voxels[flat[i]]
                if measured > 0 and measured > z - cell:
                    gone = z < measured - see_through or other
        if gone:
            flat_voxels[flat[i]] = unknown
            cleared[n_cleared] = flat[i] // layers
            n_cleared += 1
        else:
            kept[n_kept] = flat[i]
            n_kept += 1
    return kept[:n_kept], cleared[:n_cleared]


@_jit
def _set_bit(words, k):
    words[k >> 6] |= np.uint64(1) << np.uint64(k & 63)


@_jit
def _has_bit(words, k):
    return (words[k >> 6] >> np.uint64(k & 63)) & np.uint64(1) != 0


@_jit
def refresh_columns(columns, voxels, top_down, bits, ranks, label_rank, blocks, lo, hi,
                    first_category, first_channel, obstacle, obstacle_rank):  # fmt: skip
    """Re-read the top-down channels of the given columns off their voxels, the same channels
    as bits (``bits``: 64 channels a word), and each column's rank (``crops.LabelRanks``): its
    best category's, else ``obstacle_rank`` for an obstacle, else ``label_rank``'s rank for no
    category (what any label other than one gets)."""
    layers = voxels.shape[-1]
    flat_voxels = voxels.reshape(-1, layers)
    td = top_down.reshape(-1, top_down.shape[-1])
    flat_bits = bits.reshape(-1, bits.shape[-1])
    flat_ranks = ranks.reshape(-1)
    nothing = label_rank[0]
    for column in columns:
        td[column, :] = 0
        flat_bits[column, :] = 0
        blocked = False
        for z in range(lo, min(hi, layers)):
            if blocks[flat_voxels[column, z]]:
                td[column, obstacle] = 1
                _set_bit(flat_bits[column], obstacle)
                blocked = True
                break
        best = nothing
        for z in range(layers):
            v = flat_voxels[column, z]
            if v >= first_category:
                td[column, first_channel + v - first_category] = 1
                _set_bit(flat_bits[column], first_channel + v - first_category)
                best = min(best, label_rank[v])
        if best == nothing and blocked:
            best = obstacle_rank
        flat_ranks[column] = best


@_jit
def unexplored_cells(r0, r1, c0, c1, explored, origin, cell):
    """Rows, columns and centres (x, y, 0) of the cells of a window not yet explored; the
    visible-floor test only ever marks cells explored, so it can skip the others."""
    rows, cols = explored.shape
    r1, c1 = min(r1, rows - 1), min(c1, cols - 1)
    n = max(r1 - r0 + 1, 0) * max(c1 - c0 + 1, 0)
    r_out = np.empty(n, np.int64)
    c_out = np.empty(n, np.int64)
    xyz = np.zeros((n, 3), np.float64)
    k = 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            if not explored[r, c]:
                r_out[k], c_out[k] = r, c
                xyz[k, 0] = origin[0] + (c + 0.5) * cell  # MapFrame.centres
                xyz[k, 1] = origin[1] + (r + 0.5) * cell
                k += 1
    return r_out[:k], c_out[:k], xyz[:k]


@_jit
def mark_floor_seen(cam, rows, cols, depth, k, ext, camera_z, reach, floor_hit, explored):
    """Mark explored the cells whose centre (``cam``: on the floor, in camera coordinates)
    falls on a pixel that sees the floor (its hit lies below ``floor_hit``)."""
    h, w = depth.shape
    for i in range(len(cam)):
        z = cam[i, 2]
        if not z > 1e-6:  # behind the camera
            continue
        u, v = pixel_of(k, cam[i, 0], cam[i, 1], z)
        if u < 0 or u >= w or v < 0 or v >= h or not z <= reach:
            continue
        d = np.float64(depth[v, u])
        ray_x = (u + 0.5 - k[0, 2]) / k[0, 0]
        ray_y = (v + 0.5 - k[1, 2]) / k[1, 1]
        height = camera_z + d * (ray_x * ext[0, 2] + ray_y * ext[1, 2] + ext[2, 2])
        if d > 0 and height < floor_hit:
            explored[rows[i], cols[i]] = True


@_jit
def egocentric_cells(x, y, fwd, right, ahead, side, origin, cell):
    """Map rows and columns of the sample points ``(x, y) + ahead[i] * fwd + side[j] * right``
    in (i, j) order, as numpy computed them from a meshgrid (the same float64 operations in the
    same order, without the (N, 2) arrays)."""
    n_side = len(side)
    rows = np.empty(len(ahead) * n_side, np.int64)
    cols = np.empty(len(ahead) * n_side, np.int64)
    for i in range(len(ahead)):
        for j in range(n_side):
            wx = x + ahead[i] * fwd[0] + side[j] * right[0]
            wy = y + ahead[i] * fwd[1] + side[j] * right[1]
            cols[i * n_side + j] = np.int64(np.floor((wx - origin[0]) / cell))
            rows[i * n_side + j] = np.int64(np.floor((wy - origin[1]) / cell))
    return rows, cols


@_jit
def _crop_cell(i, size, sub):
    """The crop cell (a, b) of sample i of an egocentric grid sampled in (size, sub, size, sub)
    order (``crops._egocentric_cells``)."""
    return i // (sub * size * sub), (i // sub) % size


@_jit
def pooled_samples(top_down, rows, cols, size, sub):
    """(size, size, channels): per crop cell the maximum over its sub x sub samples, read at
    map cells (rows, cols); samples off the map read 0."""
    n_rows, n_cols, channels = top_down.shape
    out = np.zeros((size, size, channels), top_down.dtype)
    for i in range(len(rows)):
        r, c = rows[i], cols[i]
        if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
            continue
        a, b = _crop_cell(i, size, sub)
        for k in range(channels):  # indexed, not through per-sample row views (faster)
            v = top_down[r, c, k]
            if v > out[a, b, k]:
                out[a, b, k] = v
    return out


@_jit
def pooled_bits(bits, explored, rows, cols, size, sub, channels, explored_channel):
    """(size, size, channels) uint8: ``pooled_samples`` of a 0/1 top-down map from its bits
    (``refresh_columns``) and its explored cells: per crop cell a word-wise OR over its
    samples, then unpacked, instead of every channel of every sample."""
    n_rows, n_cols, words = bits.shape
    union = np.zeros((size, size, words), np.uint64)
    seen = np.zeros((size, size), np.bool_)
    for i in range(len(rows)):
        r, c = rows[i], cols[i]
        if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
            continue
        a, b = _crop_cell(i, size, sub)
        for w in range(words):
            union[a, b, w] |= bits[r, c, w]
        if explored[r, c]:
            seen[a, b] = True
    out = np.zeros((size, size, channels), np.uint8)
    for a in range(size):
        for b in range(size):
            for k in range(channels):
                if _has_bit(union[a, b], k):
                    out[a, b, k] = 1
            if seen[a, b]:
                out[a, b, explored_channel] = 1
    return out


@_jit
def pooled_ranks(ranks, explored, rows, cols, size, sub, nothing, free_rank):
    """(size, size) int16: per crop cell the best (lowest) rank over its sub x sub samples,
    read at map cells (rows, cols); a sample with ``nothing`` ranks ``free_rank`` where explored,
    and off the map it ranks ``nothing``. The crop's labels from one value per sample, not from
    every channel (``pooled_samples``)."""
    n_rows, n_cols = ranks.shape
    out = np.full((size, size), nothing, np.int16)
    for i in range(len(rows)):
        r, c = rows[i], cols[i]
        if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
            continue
        v = ranks[r, c]
        if v == nothing and explored[r, c]:
            v = free_rank
        a, b = _crop_cell(i, size, sub)
        if v < out[a, b]:
            out[a, b] = v
    return out


@_jit
def sample_shares(top_down, rows, cols, size, sub, obstacle, explored, first_channel):
    """(size, size, 3) uint8: per cell the share (0-255) of its sub x sub samples (map cells
    (rows, cols); off the map reads 0) holding an obstacle, explored, any object. numpy took
    the float32 mean, times 255, rounded half to even."""
    n_rows, n_cols, channels = top_down.shape
    counts = np.zeros((size, size, 3), np.int64)
    for i in range(len(rows)):
        r, c = rows[i], cols[i]
        if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
            continue
        a, b = _crop_cell(i, size, sub)
        t = top_down[r, c]
        counts[a, b, 0] += t[obstacle] != 0
        counts[a, b, 1] += t[explored] != 0
        for k in range(first_channel, channels):
            if t[k] != 0:
                counts[a, b, 2] += 1
                break
    out = np.empty((size, size, 3), np.uint8)
    n = np.float32(sub * sub)
    for a in range(size):
        for b in range(size):
            for k in range(3):
                out[a, b, k] = np.uint8(np.round(np.float32(counts[a, b, k]) / n * np.float32(255)))
    return out


@_jit
def mark_near_cells(points, camera, reach, origin, cell, grid):
    """Set ``grid``'s cells (rows y, columns x from ``origin``, ``cell`` wide) under the points
    within ``reach`` of ``camera`` (horizontally). numpy took the distance in float64 and the
    cell in the points' dtype (``origin`` and ``cell`` come in it)."""
    rows, cols = grid.shape
    # max(|dx|, |dy|) <= hypot <= |dx| + |dy|: points well outside the square of side 2 reach, or
    # well inside the diamond, are settled without np.hypot (most of its cost); the margins
    # (a billionth of reach) cover the last bits of rounding, so the outcome is np.hypot's
    outside, inside = reach * (1 + 1e-9), reach * (1 - 1e-9)
    for i in range(len(points)):
        dx = np.float64(points[i, 0]) - camera[0]
        dy = np.float64(points[i, 1]) - camera[1]
        if abs(dx) >= outside or abs(dy) >= outside:
            continue
        if not abs(dx) + abs(dy) < inside and not np.hypot(dx, dy) < reach:
            continue
        c = np.int64(np.floor((points[i, 0] - origin[0]) / cell))
        r = np.int64(np.floor((points[i, 1] - origin[1]) / cell))
        if 0 <= r < rows and 0 <= c < cols:
            grid[r, c] = True
