"""Top-down pictures of houses (PNG): rooms by type, walls, doors, furniture, objects, grid."""

from __future__ import annotations

import math
from pathlib import Path

from matplotlib.patches import Patch, Polygon, Rectangle

from maniskill_tidy.common.plotting import plt, save_figure
from maniskill_tidy.houses.navgrid import grid_array, solid_wall_segments
from maniskill_tidy.houses.schema import House

ROOM_COLORS = {
    "Kitchen": "#f6d5a8",
    "LivingRoom": "#cfe3c4",
    "Bedroom": "#c9d7f0",
    "Bathroom": "#e9c9e6",
}


def draw_house(
    house: House,
    out: Path,
    highlight: dict[str, str] | None = None,
    title: str | None = None,
    show_grid: bool = True,
    labels: bool = True,
) -> Path:
    """Draw ``house`` to ``out``; ``highlight`` maps object ids to a colour (misplaced ones).

    One figure drawn layer by layer (rooms, walls, doors, furniture, objects, labels,
    legend), bottom to top; the layers share the axes and the scale, so they stay together."""
    highlight = highlight or {}
    xs = [p[0] for r in house.rooms for p in r.polygon]
    ys = [p[1] for r in house.rooms for p in r.polygon]
    width, height = max(xs) - min(xs), max(ys) - min(ys)
    scale = 11 / max(width, height)
    fig, ax = plt.subplots(figsize=(max(width * scale, 5) + 2.5, max(height * scale, 4) + 0.8))
    for room in house.rooms:
        ax.add_patch(
            Polygon(
                room.polygon,
                closed=True,
                fc=ROOM_COLORS.get(room.type, "#ddd"),
                ec="none",
                zorder=0,
            )
        )
        x0, y0, x1, y1 = room.bounds()
        ax.text(
            (x0 + x1) / 2,
            y1 - 0.25,
            f"{room.type} ({room.id})",
            ha="center",
            va="top",
            fontsize=8,
            color="#444",
            zorder=5,
        )
    if show_grid and house.navgrid is not None:
        free = grid_array(house.navgrid)
        g = house.navgrid
        rows, cols = free.nonzero()
        ax.scatter(
            g.origin[0] + (cols + 0.5) * g.cell,
            g.origin[1] + (rows + 0.5) * g.cell,
            s=4,
            c="#4e7d4e",
            alpha=0.7,
            zorder=1,
            linewidths=0,
        )
    for a, b, _thickness in solid_wall_segments(house):
        ax.plot([a[0], b[0]], [a[1], b[1]], color="#222", lw=3, solid_capstyle="butt", zorder=4)
    for door in house.doors:
        ax.plot(*door.center, marker="s", ms=3, color="#b5651d", zorder=4)
    for f in house.furniture:
        _rect(
            ax,
            f.position,
            f.size[0],
            f.size[1],
            f.yaw,
            fc="#8d6e63" if f.parent is None else "#bcaaa4",
            alpha=0.85,
            z=2,
        )
        if f.joints:
            _front_mark(ax, f)
        if labels:
            ax.text(
                f.position[0],
                f.position[1],
                f.type,
                fontsize=5.5,
                ha="center",
                va="center",
                color="white" if f.parent is None else "black",
                zorder=6,
            )
    for o in house.objects:
        color = highlight.get(o.id, "#1565c0")
        _rect(ax, o.position, o.size[0], o.size[1], o.yaw, fc=color, alpha=1.0, z=7)
        if labels and o.id in highlight:
            ax.annotate(
                o.type,
                o.position[:2],
                xytext=(4, 4),
                textcoords="offset points",
                fontsize=7,
                color=color,
                weight="bold",
                zorder=8,
            )
    handles = [Patch(color=c, label=t) for t, c in ROOM_COLORS.items()]
    handles += [Patch(color="#8d6e63", label="furniture"), Patch(color="#1565c0", label="object")]
    if highlight:
        handles.append(Patch(color="#d32f2f", label="misplaced"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1), fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlim(min(xs) - 0.3, max(xs) + 0.3)
    ax.set_ylim(min(ys) - 0.3, max(ys) + 0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        title
        or f"{house.id}: {len(house.rooms)} rooms, {len(house.furniture)} "
        f"furniture, {len(house.objects)} objects (dots: free 0.25 m cells)",
        fontsize=9,
    )
    return save_figure(fig, out, dpi=130)


def _rect(ax, center, w, d, yaw, fc, alpha, z) -> None:
    c, s = math.cos(yaw), math.sin(yaw)
    corner = (center[0] - c * w / 2 + s * d / 2, center[1] - s * w / 2 - c * d / 2)
    ax.add_patch(
        Rectangle(
            corner, w, d, angle=math.degrees(yaw), fc=fc, ec="black", lw=0.4, alpha=alpha, zorder=z
        )
    )


def _front_mark(ax, f) -> None:
    """A short tick on the front face of articulated furniture."""
    c, s = math.cos(f.yaw), math.sin(f.yaw)
    fx, fy = f.position[0] - s * f.size[1] / 2, f.position[1] + c * f.size[1] / 2
    ax.plot(
        [fx - c * f.size[0] / 2, fx + c * f.size[0] / 2],
        [fy - s * f.size[0] / 2, fy + s * f.size[0] / 2],
        color="#ffb300",
        lw=1.5,
        zorder=3,
    )
