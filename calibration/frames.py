"""Checking calibration inputs and finding the target in each frame."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from calibration.detect import Detection, by_plausibility, markers_by_dictionary, scan
from calibration.pnp import FramePose, solve_pose
from calibration.targets import DICTIONARIES, Target, dictionary_size, short_name
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
    target: Target,
    observations: Sequence[Observation],
    need: str,
    images: Sequence[npt.NDArray[np.uint8]] = (),
) -> CalibrationError:
    """An error for too few detections, listing the marker ids that were seen instead. With
    the ``images``, when the target's own dictionary shows nothing, the other dictionaries
    are tried on a few images and the best match is named (``add dict=DICT_6X6_250``)."""
    found = sum(o.detection is not None for o in observations)
    seen = sorted({i for o in observations for i in o.seen_ids})
    text = (
        f"{target.describe()} found in {found} of {len(observations)} images ({need}); "
        f"{short_name(target.dictionary)} ids seen: {seen}"
    )
    if not seen and images:
        hint = other_dictionary_hint(images, target.dictionary)
        if hint:
            text += f"; {hint}"
    return CalibrationError(text)


#: Images tried with every dictionary when the target's own shows nothing.
HINT_IMAGES = 3


def other_dictionary_hint(images: Sequence[npt.NDArray[np.uint8]], own: str) -> str:
    """``found DICT_6X6_50 ids 0-16 (the same markers as in DICT_6X6_100, DICT_6X6_250,
    DICT_6X6_1000): add dict=DICT_6X6_50`` for the dictionary with the most markers in a few
    of the ``images`` (ties: see ``detect.by_plausibility``), or what was not found."""
    counts: dict[str, set[int]] = {}
    step = max(1, len(images) // HINT_IMAGES)
    for image in list(images)[::step][:HINT_IMAGES]:
        for name, markers in markers_by_dictionary(image).items():
            if name != own:
                counts.setdefault(name, set()).update(markers)
    if not counts:
        return "no markers of any OpenCV dictionary seen"
    best = by_plausibility({n: len(ids) for n, ids in counts.items()})[0]
    ids = sorted(counts[best])
    span = f"{ids[0]}-{ids[-1]}" if len(ids) > 2 else ", ".join(map(str, ids))
    # OpenCV's DICT_NxN_50/100/250/1000 share their first markers: a board printed from any
    # of them reads the same with the smallest that holds its ids.
    family = best.rsplit("_", 1)[0] + "_"
    larger = [
        n
        for n in DICTIONARIES
        if n != best and n.startswith(family) and dictionary_size(n) > dictionary_size(best)
    ]
    same = f" (the same markers as in {', '.join(larger)})" if larger else ""
    return f"found {best} ids {span}{same}: add dict={best}"
