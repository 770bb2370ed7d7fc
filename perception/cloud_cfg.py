"""How the scene cloud is built from a recording: crop box, depth range, downsampling,
outlier removal, the robot's own points, frames fused.

Its own module, light to import: the command line shows these defaults in its help, and
``gaide run``'s perception section extends it, so both start from the same values.
"""

from __future__ import annotations

from dataclasses import dataclass

from gaide_core import settings
from gaide_core.errors import PerceptionError


@dataclass(frozen=True, kw_only=True)
class CloudCfg:
    """Settings of :func:`perception.cloud.scene_cloud` (m; the base frame)."""

    workspace_min: tuple[float, ...] = (-1.0, -1.0, -0.05)  # m, crop box in the base frame
    workspace_max: tuple[float, ...] = (1.0, 1.0, 1.2)  # m
    min_depth: float = 0.15  # m, closer readings are discarded (D4xx minimum range)
    max_depth: float = 4.0  # m
    voxel: float = 0.01  # m, downsampling voxel (0: keep every point)
    outlier_neighbors: int = 16  # statistical outlier removal: neighbours considered (0: off)
    outlier_std: float = 2.5  # ... and the std-dev ratio beyond which a point goes
    robot_padding: float = 0.02  # m added to the robot's spheres when removing its points
    max_frames: int = 30  # depth frames fused (median) at most

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        err = PerceptionError
        lo = settings.vector(self.workspace_min, "workspace_min", length=3, unit="m", error=err)
        hi = settings.vector(self.workspace_max, "workspace_max", length=3, unit="m", error=err)
        if lo is None or hi is None:
            raise err("workspace_min and workspace_max need 3 numbers each (m)")
        if any(a >= b for a, b in zip(lo, hi, strict=True)):
            raise err(
                f"workspace_min {list(lo)} must be below workspace_max {list(hi)} on every axis"
            )
        put("workspace_min", lo)
        put("workspace_max", hi)
        put(
            "min_depth",
            settings.number(self.min_depth, "min_depth", lo=0.0, lo_open=True, unit="m", error=err),
        )
        put(
            "max_depth",
            settings.number(
                self.max_depth, "max_depth", lo=self.min_depth, lo_open=True, unit="m", error=err
            ),
        )
        put("voxel", settings.number(self.voxel, "voxel", lo=0.0, hi=0.2, unit="m", error=err))
        settings.integer(self.outlier_neighbors, "outlier_neighbors", lo=0, error=err)
        put(
            "outlier_std",
            settings.number(self.outlier_std, "outlier_std", lo=0.0, lo_open=True, error=err),
        )
        put(
            "robot_padding",
            settings.number(
                self.robot_padding, "robot_padding", lo=0.0, hi=0.5, unit="m", error=err
            ),
        )
        settings.integer(self.max_frames, "max_frames", lo=1, error=err)


__all__ = ["CloudCfg"]
