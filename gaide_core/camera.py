"""Pinhole camera intrinsics, shared by perception (a bag's CameraInfo, depth to points) and
calibration (detection and PnP on images).

Pixels follow OpenCV and ROS: ``K`` maps a point in the camera's optical frame (x right,
y down, z forward) to pixel coordinates, ``D`` holds OpenCV distortion coefficients in the
order ``distortion_model`` names (ROS ``plumb_bob``: k1, k2, p1, p2, k3).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gaide_core.errors import ConfigError, GaideError
from gaide_core.types import Array

#: Lengths of the distortion vectors OpenCV accepts (0: none).
DISTORTION_SIZES = (0, 4, 5, 8, 12, 14)


@dataclass(frozen=True, eq=False)
class Intrinsics:
    """Pinhole intrinsics of one image stream: size (px), ``K`` (3, 3), ``D`` distortion.

    Construction checks them (ConfigError naming what is wrong); :meth:`checked` raises the
    caller's stage error instead, with a prefix saying where the values came from.
    """

    width: int
    height: int
    K: Array  # (3, 3)
    distortion_model: str = "plumb_bob"  # the ROS name; RealSense reports e.g. "plumb_bob"
    D: Array = field(default_factory=lambda: np.zeros(5))

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64)
        D = np.asarray(self.D, dtype=np.float64).ravel()
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "D", D)
        if self.width <= 0 or self.height <= 0:
            raise ConfigError(f"image size must be positive, got {self.width}x{self.height}")
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ConfigError(
                f"camera matrix K must be a finite 3x3 with positive focal lengths, got "
                f"{K.tolist()}"
            )
        if D.size not in DISTORTION_SIZES or not np.all(np.isfinite(D)):
            raise ConfigError(
                f"distortion D must hold 4, 5, 8, 12 or 14 finite OpenCV coefficients (or "
                f"none), got {D.tolist()}"
            )

    @classmethod
    def checked(
        cls,
        width: int,
        height: int,
        K: npt.ArrayLike,
        D: npt.ArrayLike | None = None,
        distortion_model: str = "plumb_bob",
        *,
        error: type[GaideError] = ConfigError,
        where: str = "",
    ) -> Intrinsics:
        """Intrinsics from untrusted values; ``error`` (prefixed with ``where``) if invalid."""
        try:
            return cls(
                int(width),
                int(height),
                np.asarray(K, dtype=np.float64),
                distortion_model,
                np.zeros(5) if D is None else np.asarray(D, dtype=np.float64),
            )
        except (ConfigError, TypeError, ValueError) as err:
            raise error(f"{where}: {err}" if where else str(err)) from err

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])


__all__ = ["DISTORTION_SIZES", "Intrinsics"]
