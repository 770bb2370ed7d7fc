"""The run's pictures of the scene (PNG bytes, matplotlib's Agg backend: no display, no GPU,
a second or two each): the perceived cloud, and the planned path as robot poses in it.

Everything is drawn in the robot's base frame (m); the 3D views look from the calibrated
camera's side of the scene, so they match what the camera saw.
"""

from __future__ import annotations

import io

import matplotlib

from gaide_core.types import Array

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from planning.collision import CollisionChecker
from planning.plot import draw_spheres

MAX_POINTS = 12_000  # cloud points drawn at most (an even subset)


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()


def _subset(points: Array, colors: Array | None) -> tuple[Array, Array]:
    step = max(1, len(points) // MAX_POINTS)
    pts = points[::step]
    if colors is not None:
        return pts, np.clip(colors[::step], 0.0, 1.0)
    z = pts[:, 2]
    shade = (z - z.min()) / max(float(np.ptp(z)), 1e-9)
    return pts, np.stack([0.35 + 0.45 * shade] * 3, axis=1)


def _view(ax, eye: Array, lookat: Array) -> None:  # type: ignore[no-untyped-def]
    d = np.asarray(eye, float) - np.asarray(lookat, float)
    ax.view_init(
        elev=float(np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1])))),
        azim=float(np.degrees(np.arctan2(d[1], d[0]))),
    )


def _limits(ax, pts: Array) -> None:  # type: ignore[no-untyped-def]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 0.3)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        setter(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")


def _base_axes(ax, length: float = 0.2) -> None:  # type: ignore[no-untyped-def]
    for axis, colour in zip(np.eye(3) * length, ("r", "g", "b"), strict=True):
        ax.quiver(0, 0, 0, *axis, color=colour, linewidth=2)


def cloud_png(points: Array, colors: Array | None, *, eye: Array, title: str) -> bytes:
    """The cloud (N, 3) (base frame, RGB in [0, 1] or None: shaded by height) seen from
    ``eye`` (m), with the base frame's axes."""
    pts, cols = _subset(np.asarray(points, float), colors)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(*pts.T, c=cols, s=1.5, linewidths=0, depthshade=False)
    _base_axes(ax)
    _view(ax, eye, pts.mean(axis=0))
    _limits(ax, np.vstack([pts, np.zeros((1, 3))]))
    ax.set_title(title)
    fig.tight_layout()
    return _png(fig)


def poses_along(path: Array, n: int) -> Array:
    """(n, dof) configurations evenly spaced by joint-space arc length along ``path``
    (K, dof), both ends included."""
    P = np.asarray(path, float)
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(P[:1], n, axis=0)
    targets = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(targets, s, P[:, j]) for j in range(P.shape[1])], axis=1)


def path_png(
    checker: CollisionChecker,
    path: Array,
    points: Array,
    colors: Array | None,
    *,
    eye: Array,
    poses: int,
    title: str,
) -> bytes:
    """The robot's spheres at ``poses`` configurations along ``path`` (K, dof), start blue to
    goal orange, over the cloud; the end effector's trace as a line. Left: seen from
    ``eye``; right: from above."""
    robot = checker.robot
    pts, cols = _subset(np.asarray(points, float), colors)
    Q = poses_along(path, poses)
    dense = poses_along(path, 120)
    trace = np.array([robot.frame_pose(q)[:3, 3] for q in dense])
    centres = checker.sphere_centers(Q)  # (poses, S, 3)
    tint = plt.get_cmap("coolwarm")(np.linspace(0.0, 1.0, poses))
    fig = plt.figure(figsize=(15, 7.5))
    grid = fig.add_gridspec(1, 2, width_ratios=(1.15, 1.0), wspace=0.3)
    ax = fig.add_subplot(grid[0], projection="3d")
    ax.scatter(*pts.T, c=cols, s=1.2, linewidths=0, depthshade=False, alpha=0.7)
    for k in range(poses):
        alpha = 0.45 if k in (0, poses - 1) else 0.2
        draw_spheres(ax, centres[k], checker.radii, to_hex(tint[k]), alpha=alpha)
    ax.plot(*trace.T, color="k", lw=2)
    _base_axes(ax)
    _view(ax, eye, trace.mean(axis=0))
    _limits(ax, np.vstack([pts, centres.reshape(-1, 3)]))
    ax.set_title("seen from the camera's side")
    top = fig.add_subplot(grid[1])
    order = np.argsort(pts[:, 2])  # higher points drawn last: obstacles over the table
    z = pts[order, 2]
    light = float(z.min() - 0.2 * max(float(np.ptp(z)), 1e-3))  # the lowest points stay visible
    dots = top.scatter(
        pts[order, 0], pts[order, 1], c=z, cmap="Greys", vmin=light, s=1.5, linewidths=0
    )
    fig.colorbar(dots, ax=top, shrink=0.7, label="cloud height z (m)")
    for k in range(poses):
        for c, r in zip(centres[k], checker.radii, strict=True):
            top.add_patch(Circle((c[0], c[1]), r, color=tint[k], alpha=0.25, lw=0))
    top.plot(trace[:, 0], trace[:, 1], color="k", lw=2, label="end effector")
    top.plot(*trace[0, :2], "o", color=tint[0], ms=9, label="start")
    top.plot(*trace[-1, :2], "o", color=tint[-1], ms=9, label="goal")
    top.set_aspect("equal")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title("from above")
    top.legend(loc="upper right", fontsize=8)
    top.grid(alpha=0.3)
    fig.suptitle(title)
    return _png(fig)
