"""Pictures of the robot's spheres in a scene (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

from gaide_core.atomic import write_file_atomic
from gaide_core.errors import PlanningError
from gaide_core.types import Array

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from planning.collision import CollisionChecker


def draw_spheres(ax, centers: Array, radii: Array, color: str, alpha: float = 0.35) -> None:  # type: ignore[no-untyped-def]
    u, v = np.mgrid[0 : 2 * np.pi : 12j, 0 : np.pi : 8j]
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
    for c, r in zip(centers, radii, strict=True):
        x, y, z = (unit * r) + c[:, None, None]
        ax.plot_surface(x, y, z, color=color, alpha=alpha, linewidth=0, shade=True)


def render_scene(
    path: str | Path,
    checker: CollisionChecker,
    configurations: list[Array],
    cloud: Array | None = None,
    title: str = "",
    colors: tuple[str, ...] = ("tab:blue", "tab:orange", "tab:green", "tab:red"),
) -> None:
    """Write a PNG of the robot's spheres at each configuration over the scene cloud."""
    fig = plt.figure(figsize=(8, 7), dpi=110)
    ax = fig.add_subplot(projection="3d")
    if cloud is not None and len(cloud):
        pick = cloud[:: max(1, len(cloud) // 6000)]
        ax.scatter(pick[:, 0], pick[:, 1], pick[:, 2], s=1.0, c="dimgray", alpha=0.6, linewidths=0)
    for i, q in enumerate(configurations):
        centers = checker.sphere_centers(np.asarray(q, float)[None])[0]
        draw_spheres(ax, centers, checker.radii, colors[i % len(colors)])
    ax.quiver(0, 0, 0, 0.2, 0, 0, color="r")
    ax.quiver(0, 0, 0, 0, 0.2, 0, color="g")
    ax.quiver(0, 0, 0, 0, 0, 0.2, color="b")
    ax.set_xlim(-0.9, 0.9)
    ax.set_ylim(-0.9, 0.9)
    ax.set_zlim(-0.1, 1.1)
    ax.set_box_aspect((1.8, 1.8, 1.2))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(title)
    try:
        write_file_atomic(path, lambda tmp: fig.savefig(tmp), PlanningError)
    finally:
        plt.close(fig)
