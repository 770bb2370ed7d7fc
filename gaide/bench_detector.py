"""The tag detector (``calibration.detect``) against AprilTag 3 (pupil-apriltags) on rendered
images with known corners (``gaide.synthetic.marker_images``).

- ``detector_recall_vs_reference``: share of the tags AprilTag 3 finds that ours finds too,
  over the seeded tag36h11 cases of ``tag_cases`` (small, far, tilted 60-70 degrees, blurred,
  at the image border, several per image, noisy; 640x480).
- ``corner_err_px`` / ``corner_err_p95_px``: median / 95th percentile distance (px) of our
  corners from the true ones, over every tag we find; ``corner_err_px_reference`` /
  ``corner_err_p95_px_reference``: the same for AprilTag 3 over the tags it finds.
- ``dict_cases_found``: share of rendered single tags, grids and ChArUco boards of seven
  dictionaries (``BENCH_DICTIONARIES``) found whole by ``scan`` (every tag id and, for
  ChArUco, every chessboard corner).
- ``detector_ms_per_image`` / ``reference_ms_per_image``: time of ``detect_markers`` (both
  finders) / AprilTag 3 per 640x480 image; ``scan_ms_per_image``: ``scan`` of one tag, the
  path calibration takes (the second finder runs only when the first misses the tag).

AprilTag 3's conventions, checked on these images: its corners run TR, TL, BL, BR in
OpenCV's terms (``[1, 0, 3, 2]`` reorders them) and sit +0.5 px off in u and v (pixel
centres at (0.5, 0.5); mean offset measured +0.49, +0.50), which is removed. It runs with
``quad_decimate=1`` (full resolution, its best on small tags) and ``refine_edges``.
"""

from __future__ import annotations

import time
from functools import lru_cache
from typing import Any

import numpy as np

from calibration.detect import detect_markers, scan
from calibration.targets import DEFAULT_DICTIONARY, Charuco, SingleTag
from gaide.synthetic.marker_images import tag_cases, target_cases
from gaide_core.errors import ConfigError
from gaide_core.types import Array

#: The dictionaries of ``dict_cases_found``.
BENCH_DICTIONARIES = (
    "DICT_4X4_50",
    "DICT_5X5_100",
    "DICT_6X6_250",
    "DICT_7X7_1000",
    "DICT_ARUCO_ORIGINAL",
    "DICT_APRILTAG_36h11",
    "DICT_APRILTAG_25h9",
)
#: AprilTag 3's corner order to OpenCV's TL, TR, BR, BL, and its pixel-centre offset (px).
REFERENCE_ORDER = [1, 0, 3, 2]
REFERENCE_OFFSET = 0.5


@lru_cache(maxsize=1)
def reference_detector() -> Any:
    """AprilTag 3 (pupil-apriltags) for tag36h11 at full resolution, one thread; one per
    process, never destroyed (see ``_kept``)."""
    try:
        from pupil_apriltags import Detector  # type: ignore[import-untyped]
    except ImportError as err:
        raise ConfigError(
            "the detector benchmark compares with AprilTag 3: install the dev dependency "
            "pupil-apriltags (pip install pupil-apriltags, or pip install -e '.[dev]')"
        ) from err
    return _kept(Detector)(families="tag36h11", nthreads=1, quad_decimate=1.0, refine_edges=1)


def _kept(detector_class: Any) -> Any:
    """``detector_class`` without its destructor. pupil-apriltags' ``Detector.__del__`` frees
    the tag families before the C detector that still points at them, a use after free that
    corrupted the heap and aborted the process later, in an unrelated allocation (seen with
    pupil-apriltags 1.0.4; glibc's malloc check shows it in ``__del__``). The one detector a
    process makes is left for the OS to reclaim."""

    class KeptDetector(detector_class):  # type: ignore[misc, valid-type]
        def __del__(self) -> None:
            pass

    return KeptDetector


def reference_corners(detector: Any, image: Any) -> dict[int, Array]:
    """AprilTag 3's tags in a gray uint8 image: (4, 2) corners (px, TL, TR, BR, BL, pixel
    centres at integers) by id."""
    return {
        int(d.tag_id): np.asarray(d.corners, np.float64)[REFERENCE_ORDER] - REFERENCE_OFFSET
        for d in detector.detect(image)
    }


def run_detector_benchmark(seed: int = 0, *, per_kind: int = 8, poses: int = 2) -> dict[str, float]:
    """The figures of the module docstring on ``per_kind`` images of each tag case kind and
    ``poses`` images of each dictionary target, all drawn from ``seed``."""
    reference = reference_detector()
    cases = tag_cases(seed, per_kind)
    found_ref = found_both = 0
    err: list[Array] = []
    err_ref: list[Array] = []
    ours_s = ref_s = scan_s = 0.0
    for case in cases:
        t0 = time.perf_counter()
        theirs = reference_corners(reference, case.image)
        t1 = time.perf_counter()
        ours = detect_markers(case.image, DEFAULT_DICTIONARY)
        t2 = time.perf_counter()
        tag_id = next(iter(case.corners))
        scan(case.image, SingleTag(tag_id, 0.08), case.K)
        scan_s += time.perf_counter() - t2
        ref_s += t1 - t0
        ours_s += t2 - t1
        for tag_id, truth in case.corners.items():
            if tag_id in theirs:
                found_ref += 1
                found_both += tag_id in ours
                err_ref.append(np.linalg.norm(theirs[tag_id] - truth, axis=1))
            if tag_id in ours:
                err.append(np.linalg.norm(ours[tag_id] - truth, axis=1))
    e, e_ref = np.concatenate(err), np.concatenate(err_ref)
    dict_cases = target_cases(BENCH_DICTIONARIES, seed, poses)
    whole = 0
    for tc in dict_cases:
        det = scan(tc.image, tc.target, tc.K)
        corners_ok = not isinstance(tc.target, Charuco) or len(det.object_points) == len(
            tc.target.chessboard_corners
        )
        whole += det.found and set(det.ids) == set(tc.target.ids) and corners_ok
    n = len(cases)
    return {
        "detector_recall_vs_reference": found_both / max(found_ref, 1),
        "corner_err_px": float(np.median(e)),
        "corner_err_p95_px": float(np.percentile(e, 95)),
        "corner_err_px_reference": float(np.median(e_ref)),
        "corner_err_p95_px_reference": float(np.percentile(e_ref, 95)),
        "dict_cases_found": whole / len(dict_cases),
        "detector_ms_per_image": 1e3 * ours_s / n,
        "reference_ms_per_image": 1e3 * ref_s / n,
        "scan_ms_per_image": 1e3 * scan_s / n,
        "tags_true": float(sum(len(c.corners) for c in cases)),
        "tags_found_reference": float(found_ref),
        "tags_found": float(len(err)),
    }
