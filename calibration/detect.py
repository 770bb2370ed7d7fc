"""Finding a calibration target in an image: tag corners (or ChArUco corners) with subpixel
accuracy, paired with their points in the target frame.

Tags are found by OpenCV's ``ArucoDetector`` with ``CORNER_REFINE_APRILTAG``: its AprilTag
quad finder fits lines to the tag's edges, so the corners are subpixel, and it still finds a
tag turned 70 degrees away whose white border is two pixels wide, where the contour finder
used with ``CORNER_REFINE_SUBPIX`` gives up (seen on the real photos in ../shared/data).
The contour finder in turn finds some small, dim tags the quad finder drops, so it runs as
well when the first pass misses tags of the target.
AprilTag's corner code puts pixel centres at (0.5, 0.5) where OpenCV puts them at (0, 0)
(AprilRobotics/apriltag#121), and OpenCV's port keeps that: on rendered images its corners
sit +0.45..+0.49 px off in u and v, a bias that moved poses by about 1 mm at 0.6 m. The
corners are shifted back by half a pixel (what is left: below 0.07 px). ChArUco corners come
from ``CharucoDetector``, which refines them with ``cornerSubPix``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
import numpy.typing as npt

from calibration.targets import (
    DEFAULT_DICTIONARY,
    Charuco,
    Target,
    dictionary_name,
    get_dictionary,
)
from gaide_core.errors import CalibrationError
from gaide_core.types import Array

log = logging.getLogger(__name__)

#: Fewest target points a detection needs to give a pose.
MIN_POINTS = 4
#: Pixel-centre offset (px) of corners refined by the AprilTag code, removed from them.
APRILTAG_PIXEL_OFFSET = 0.5


@dataclass(frozen=True, eq=False)
class Detection:
    """Target points found in one image.

    ``object_points``: (N, 3) in the target frame (m); ``image_points``: (N, 2) pixels (u
    right, v down, pixel centres at integers); ``point_ids``: (N,) the tag id of each point's
    tag (ChArUco: the chessboard corner id); ``ids``: the target's tag ids seen;
    ``foreign_ids``: ids of the target's dictionary seen that do not belong to it;
    ``marker_corners``: (M, 4, 2) pixels of the target's tags seen, for drawing.
    """

    object_points: Array
    image_points: Array
    point_ids: npt.NDArray[np.int64]
    ids: tuple[int, ...]
    foreign_ids: tuple[int, ...]
    marker_corners: Array

    @property
    def found(self) -> bool:
        """True when enough non-collinear points were found to solve a pose."""
        pts = self.object_points
        if len(pts) < MIN_POINTS:
            return False
        centred = pts - pts.mean(axis=0)
        s = np.linalg.svd(centred, compute_uv=False)
        return bool(s[1] > 1e-6 * max(s[0], 1e-12))

    def seen_text(self) -> str:
        """All tag ids seen, for messages: ``ids seen: [0, 5]``."""
        return f"ids seen: {sorted({*self.ids, *self.foreign_ids})}"


def to_gray(image: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """Grayscale copy of an (H, W) gray, (H, W, 3) RGB or (H, W, 4) RGBA uint8 image."""
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise CalibrationError(f"images must be uint8, got {image.dtype}")
    if image.ndim == 2:
        return image
    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_RGB2GRAY if image.shape[2] == 3 else cv2.COLOR_RGBA2GRAY
        return np.asarray(cv2.cvtColor(image, code), np.uint8)
    raise CalibrationError(
        f"an image must be (H, W) gray or (H, W, 3) RGB, got shape {image.shape}"
    )


@lru_cache(maxsize=64)
def _marker_detector(refinement: int, dictionary: str) -> cv2.aruco.ArucoDetector:
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = refinement
    return cv2.aruco.ArucoDetector(get_dictionary(dictionary), params)


def _detect_with(gray: npt.NDArray[np.uint8], refinement: int, dictionary: str) -> dict[int, Array]:
    corners, ids, _ = _marker_detector(refinement, dictionary).detectMarkers(gray)
    if ids is None:
        return {}
    offset = APRILTAG_PIXEL_OFFSET if refinement == cv2.aruco.CORNER_REFINE_APRILTAG else 0.0
    return {
        int(i): np.asarray(c, np.float64).reshape(4, 2) - offset
        for c, i in zip(corners, np.ravel(ids), strict=True)
    }


def _markers(
    gray: npt.NDArray[np.uint8], wanted: set[int], dictionary: str = DEFAULT_DICTIONARY
) -> dict[int, Array]:
    """Tag corners (4, 2) by id. The AprilTag quad finder first; when it misses some of the
    ``wanted`` ids, OpenCV's contour finder (``CORNER_REFINE_SUBPIX``) adds the tags it
    finds that the first did not (it finds small, dim tags the quad finder drops)."""
    found = _detect_with(gray, cv2.aruco.CORNER_REFINE_APRILTAG, dictionary)
    if not wanted <= found.keys():
        extra = _detect_with(gray, cv2.aruco.CORNER_REFINE_SUBPIX, dictionary)
        found.update({i: c for i, c in extra.items() if i not in found})
    return found


def _empty(ids: tuple[int, ...], foreign: tuple[int, ...], corners: Array) -> Detection:
    return Detection(
        np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), ids, foreign, corners
    )


def scan(
    image: npt.NDArray[np.uint8], target: Target, K: Array, D: Array | None = None
) -> Detection:
    """Look for ``target`` in ``image`` (gray or RGB uint8); always returns a ``Detection``,
    with no points when the target is absent (``found`` is then False).

    ``K``: (3, 3) camera matrix (px); ``D``: OpenCV distortion coefficients (or None). They
    guide the ChArUco corner interpolation; tags need neither.
    """
    gray = to_gray(image)
    own = set(target.ids)
    markers = _markers(gray, own, target.dictionary)
    ids = sorted(markers)
    mine = [(markers[i], i) for i in ids if i in own]
    seen = tuple(sorted({i for _, i in mine}))
    foreign = tuple(sorted({i for i in ids if i not in own}))
    marker_corners = np.array([c for c, _ in mine]).reshape(-1, 4, 2)
    if not mine:
        return _empty(seen, foreign, marker_corners)
    if isinstance(target, Charuco):
        return _charuco(gray, target, K, D, mine, seen, foreign, marker_corners)
    obj = np.concatenate([target.marker_corners(i) for _, i in mine])
    img = np.concatenate([c for c, _ in mine])
    pids = np.repeat(np.array([i for _, i in mine], np.int64), 4)
    return Detection(obj, img, pids, seen, foreign, marker_corners)


def _charuco(
    gray: npt.NDArray[np.uint8],
    target: Charuco,
    K: Array,
    D: Array | None,
    mine: list[tuple[Array, int]],
    seen: tuple[int, ...],
    foreign: tuple[int, ...],
    marker_corners: Array,
) -> Detection:
    params = cv2.aruco.CharucoParameters()
    params.cameraMatrix = np.asarray(K, np.float64)
    params.distCoeffs = np.zeros(5) if D is None else np.asarray(D, np.float64).ravel()
    detector = cv2.aruco.CharucoDetector(target.board, params)
    m_corners = tuple(c.reshape(1, 4, 2).astype(np.float32) for c, _ in mine)
    m_ids = np.array([i for _, i in mine], np.int32).reshape(-1, 1)
    ch_corners, ch_ids, _, _ = detector.detectBoard(gray, markerCorners=m_corners, markerIds=m_ids)
    if ch_ids is None or len(ch_ids) == 0:
        log.debug("ChArUco: tags %s seen but no chessboard corner interpolated", seen)
        return _empty(seen, foreign, marker_corners)
    cids = np.ravel(ch_ids).astype(np.int64)
    obj = target.chessboard_corners[cids]
    img = np.asarray(ch_corners, np.float64).reshape(-1, 2)
    return Detection(obj, img, cids, seen, foreign, marker_corners)


def detect(
    image: npt.NDArray[np.uint8], target: Target, K: Array, D: Array | None = None
) -> Detection | None:
    """``target`` in ``image`` (gray or RGB uint8), or None if too few of its points were
    found (use ``scan`` to learn which other tag ids were seen)."""
    detection = scan(image, target, K, D)
    return detection if detection.found else None


def detect_markers(
    image: npt.NDArray[np.uint8], dictionary: str = DEFAULT_DICTIONARY
) -> dict[int, Array]:
    """Every marker of ``dictionary`` (any name ``targets.dictionary_name`` reads) in
    ``image`` (gray or RGB uint8): its (4, 2) corners (px, OpenCV's order TL, TR, BR, BL,
    pixel centres at integers) by id."""
    return _markers(to_gray(image), set(), dictionary_name(dictionary))
