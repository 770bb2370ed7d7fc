"""Depth seen from the color camera: each color pixel gets the depth (m, color frame z) of the
nearest depth point that projects onto it, NaN where none does."""

from __future__ import annotations

import numpy as np

from gaide_core.errors import PerceptionError
from gaide_core.transforms import apply
from gaide_core.types import Array
from perception.depth import Deprojector, project
from perception.frames import Frames


def depth_in_color(frames: Frames, index: int, deprojector: Deprojector | None = None) -> Array:
    """(H, W) depth in metres aligned to color image ``index`` (the depth frame nearest in
    time), z-buffered so that the nearest surface wins."""
    if frames.depth is None or frames.color is None or len(frames.depth) == 0:
        raise PerceptionError(f"{frames.source}: aligning depth to color needs both streams")
    if frames.depth_units is None:
        raise PerceptionError(f"{frames.source}: depth units unknown")
    stamp = frames.color.stamps_ns[index]
    j = int(np.argmin(np.abs(frames.depth.stamps_ns - stamp)))
    raw = frames.depth.images[j].astype(np.float64) * frames.depth_units
    raw[raw == 0] = np.nan
    dep = deprojector or Deprojector(frames.depth.intrinsics)
    pts, _ = dep.points(raw, 0.05, 20.0)
    T = frames.T_color_depth if frames.T_color_depth is not None else np.eye(4)
    pc = apply(T, pts)
    intr = frames.color.intrinsics
    uv, inside = project(pc, intr)
    cols = np.rint(uv[inside]).astype(np.int64)
    flat = cols[:, 1] * intr.width + cols[:, 0]
    out = np.full(intr.width * intr.height, np.inf)
    np.minimum.at(out, flat, pc[inside, 2])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(intr.height, intr.width)
