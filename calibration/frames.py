"""Checking calibration inputs and finding the target in each frame."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from calibration.detect import Detection, scan
from calibration.pnp import FramePose, solve_pose
from calibration.targets import Target
from gaide_core.camera import Intrinsics
from gaide_core.errors import CalibrationError
from gaide_core.types import Array

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Observation:
    """The target in one frame: its ``detection`` and PnP ``pose`` (``T_cam_target``), both
    None with a ``reason`` when it was not found; ``seen_ids``: every tag id seen."""

    index: int
    stamp_ns: int | None
    detection: Detection | None
    pose: FramePose | None
    seen_ids: tuple[int, ...]
    reason: str = ""


def check_camera(images: Sequence[npt.NDArray[np.uint8]], K: Array, D: Array | None) -> Intrinsics:
    """Validate the images (a non-empty sequence, all one size) and the intrinsics."""
    if len(images) == 0:
        raise CalibrationError("no images given: calibration needs at least one")
    shapes = {np.shape(im)[:2] for im in images}
    if len(shapes) != 1:
        raise CalibrationError(f"images differ in size {sorted(shapes)}: give one camera's images")
    height, width = shapes.pop()
    return Intrinsics.checked(width, height, K, D, error=CalibrationError)


def check_stamps(stamps_ns: Sequence[int] | None, n: int) -> list[int | None]:
    """Per-frame stamps (ns), or Nones; their count must match the images."""
    if stamps_ns is None:
        return [None] * n
    if len(stamps_ns) != n:
        raise CalibrationError(f"{len(stamps_ns)} stamps for {n} images: give one per image")
    return [int(s) for s in stamps_ns]


def observe(
    images: Sequence[npt.NDArray[np.uint8]],
    camera: Intrinsics,
    target: Target,
    stamps: Sequence[int | None],
) -> list[Observation]:
    """Detect the target and solve its pose in every image."""
    out = []
    for i, (image, stamp) in enumerate(zip(images, stamps, strict=True)):
        det = scan(image, target, camera.K, camera.D)
        seen = tuple(sorted({*det.ids, *det.foreign_ids}))
        if not det.found:
            reason = f"{target.describe()} not found ({det.seen_text()})"
            out.append(Observation(i, stamp, None, None, seen, reason))
            continue
        pose = solve_pose(det, target, camera.K, camera.D)
        out.append(Observation(i, stamp, det, pose, seen))
    n_found = sum(o.pose is not None for o in out)
    log.info("%s found in %d of %d images", target.describe(), n_found, len(out))
    return out


def not_found_error(
    target: Target, observations: Sequence[Observation], need: str
) -> CalibrationError:
    """An error for too few detections, listing the tag ids that were seen instead."""
    found = sum(o.detection is not None for o in observations)
    seen = sorted({i for o in observations for i in o.seen_ids})
    return CalibrationError(
        f"{target.describe()} found in {found} of {len(observations)} images ({need}); "
        f"tag36h11 ids seen: {seen}"
    )
