"""The virtual RealSense: intrinsics of both streams, their extrinsics and a depth noise model."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gaide_core.camera import Intrinsics
from gaide_core.errors import ConfigError
from gaide_core.transforms import make_transform
from gaide_core.types import Array


def look_at(eye: npt.ArrayLike, target: npt.ArrayLike) -> Array:
    """T_base_cam of an optical frame (x right, y down, z forward) at ``eye`` looking at
    ``target`` (base frame, m), with the image's up towards base +z."""
    e, t = np.asarray(eye, float), np.asarray(target, float)
    z = (t - e) / np.linalg.norm(t - e)
    x = np.cross(np.array([0.0, 0.0, -1.0]), z)
    if np.linalg.norm(x) < 1e-6:
        raise ConfigError("camera looks straight up or down; give it a tilt")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return make_transform(np.stack([x, y, z], axis=1), e)


def d435_like(width: int = 640, height: int = 480) -> tuple[Intrinsics, Intrinsics]:
    """Color and depth intrinsics close to a D435's at 640x480 (scaled for other sizes)."""
    s = width / 640.0
    color = Intrinsics(
        width,
        height,
        np.array([[615.0 * s, 0, 320.0 * s - 0.3], [0, 615.0 * s, 240.0 * s + 0.4], [0, 0, 1]]),
    )
    depth = Intrinsics(
        width, height, np.array([[390.0 * s, 0, 321.0 * s], [0, 390.0 * s, 239.0 * s], [0, 0, 1]])
    )
    return color, depth


@dataclass(frozen=True, kw_only=True)
class DepthNoise:
    """RealSense-like depth: error grows with the square of the distance (stereo), readings
    are quantized to depth units, and pixels drop out at grazing angles and at random."""

    sigma_at_1m: float = 0.002  # m, standard deviation at 1 m (scales with z^2)
    depth_units: float = 0.001  # m per unit
    dropout: float = 0.005  # share of pixels lost at random
    grazing_cos: float = 0.12  # |cos| of the incidence angle below which a pixel is lost
    max_range: float = 6.0  # m

    def __post_init__(self) -> None:
        if self.sigma_at_1m < 0 or not 0 <= self.dropout < 1 or self.depth_units <= 0:
            raise ConfigError("depth noise needs sigma >= 0, 0 <= dropout < 1, depth_units > 0")

    def apply(
        self, z: Array, cos_incidence: Array, rng: np.random.Generator
    ) -> npt.NDArray[np.uint16]:
        """Raw depth image (uint16 units) from true z (m, NaN where nothing was hit)."""
        noisy = z + rng.normal(size=z.shape) * self.sigma_at_1m * np.nan_to_num(z) ** 2
        lost = ~np.isfinite(z) | (np.abs(cos_incidence) < self.grazing_cos) | (z > self.max_range)
        lost |= rng.random(z.shape) < self.dropout
        raw = np.rint(np.where(lost, 0.0, noisy) / self.depth_units)
        return np.clip(raw, 0, 65535).astype(np.uint16)


@dataclass(frozen=True, kw_only=True)
class VirtualCamera:
    color: Intrinsics
    depth: Intrinsics
    T_base_cam: Array  # (4, 4) color optical frame in the base frame
    # depth optical frame in the color frame: a D435's depth (left IR) sits ~15 mm beside it
    T_color_depth: Array = field(
        default_factory=lambda: make_transform(translation=np.array([-0.015, 0.0002, 0.0003]))
    )
    noise: DepthNoise = field(default_factory=DepthNoise)

    @property
    def T_base_depth(self) -> Array:
        return self.T_base_cam @ self.T_color_depth
