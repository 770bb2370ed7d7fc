"""Finding a calibration target in an image: tag corners (or ChArUco corners) with subpixel
accuracy, paired with their points in the target frame.

Tags are found in two passes of OpenCV's ``ArucoDetector``, both then refined by
``refine_marker_edges``:

- the contour finder (adaptive thresholds at four window sizes, ``CORNER_REFINE_NONE``): fast
  (about 10 ms for 640x480), and with the decoding settings below it finds every rendered
  tag AprilTag 3 (pupil-apriltags) finds, small (15 px), blurred, noisy and edge-touching ones
  included (``gaide.bench_detector``);
- the AprilTag quad finder (``CORNER_REFINE_APRILTAG``, 5-10x slower at full resolution):
  it still finds a tag turned 70 degrees away whose white border is two pixels wide, where
  the contour finder gives up (seen on the real photos in ../shared/data), and its quads
  follow the black square where a shadow next to the tag leads the contour finder astray.
  It runs at full resolution when the first pass finds nothing, misses a wanted tag or
  leaves one whose edge fit fails its check, and else at half resolution for
  ``detect_markers`` and ``markers_by_dictionary`` (see ``_markers``).

The corners OpenCV gives are pixel-accurate at best (the contour finder's come from a polygon
through pixel centres; the quad finder's are fitted to thresholded pixels). Each marker's four
outer edges are therefore fitted again on the gray image (``refine_marker_edges``), which
brings the median corner error on rendered tags to about 0.03 px (AprilTag 3 with
``refine_edges``: about 0.07 px).

AprilTag's corner code puts pixel centres at (0.5, 0.5) where OpenCV puts them at (0, 0)
(AprilRobotics/apriltag#121), and OpenCV's port keeps that: the quad finder's corners sit
+0.45..+0.49 px off in u and v. They are shifted back by half a pixel before the edge fit
(which then starts closer; the fit itself samples the gray image with pixel centres at
integers). ChArUco corners come from ``CharucoDetector``, fed the refined marker corners,
which refines them with ``cornerSubPix``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
import numpy.typing as npt

from calibration.targets import (
    DEFAULT_DICTIONARY,
    DICTIONARIES,
    Charuco,
    Target,
    dictionary_name,
    dictionary_size,
    get_dictionary,
    marker_cells,
)
from gaide_core.errors import CalibrationError
from gaide_core.types import Array

log = logging.getLogger(__name__)

#: Fewest target points a detection needs to give a pose.
MIN_POINTS = 4
#: Pixel-centre offset (px) of corners found by the AprilTag quad code, removed from them.
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


#: Smallest marker perimeter (px) the contour finder considers, whatever the image size
#: (OpenCV's default, 3 % of the larger image side, is 58 px in a 1920 px wide image).
MIN_PERIMETER_PX = 40.0
#: Decimation of the AprilTag quad finder's image when it only double-checks the contour
#: finder (``_markers``).
QUAD_DECIMATE = 2.0
#: Edge fit (``refine_marker_edges``): half-width (px) of the window searched across an edge,
#: at most (it also stays within half a cell inside the tag and 0.8 cell outside it).
EDGE_SEARCH_PX = 2.5
#: Edge fit: passes, each re-centring its windows on the edges of the last.
EDGE_PASSES = 2
#: Edge fit: a side is wrong when the middle of its black border is brighter than this
#: share of the way from the tag's black to its surroundings' white (0 black, 1 white).
#: Measured on right fits: 0.31 at most (755 rendered markers of every dictionary, tilted
#: up to 70 degrees, blurred up to 2 px), 0.2 (the real photos); a side fitted to the edge
#: of a shadow beside the tag (real photo, turned 60 degrees): 1.01.
BORDER_WHITENESS = 0.6


def _parameters(
    refinement: int, min_perimeter_rate: float, decimate: float = 0.0
) -> cv2.aruco.DetectorParameters:
    """OpenCV's detector settings, with these changes (chosen on rendered tag36h11 tags
    15-90 px wide against AprilTag 3's detections, see ``gaide.bench_detector``):

    - ``minDistanceToBorder`` 0 (was 3 px): tags whose corner is within 3 px of the image
      border are found (the edge fit keeps its samples inside the image);
    - ``perspectiveRemovePixelPerCell`` 8 (was 4) and ``perspectiveRemoveIgnoredMarginPerCell``
      0.3 (was 0.13): each cell's bit is read from its middle 40 %, finely sampled, so small,
      blurred or tilted tags, whose pre-refinement corners can be a pixel off (half a cell of
      a 15 px tag), still decode (recall 0.98 -> 1.0 of AprilTag 3's);
    - ``adaptiveThreshWinSizeMax`` 33 (was 23): a fourth threshold window, for tags whose
      black square spans many windows;
    - ``minMarkerPerimeterRate``: 3 % of the larger image side or ``MIN_PERIMETER_PX``,
      whichever is smaller, so that large images keep their small tags;
    - ``aprilTagQuadDecimate``: ``decimate`` (0: none, OpenCV's default), see ``_markers``.

    ``errorCorrectionRate`` stays 0.6: at that rate the 36h11 tags decoded on clutter gave no
    false positives; the 16h5 family (two correctable bits) is prone to them anyway, which
    ``markers_by_dictionary`` leaves to its caller to weigh.
    """
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = refinement
    params.minDistanceToBorder = 0
    params.perspectiveRemovePixelPerCell = 8
    params.perspectiveRemoveIgnoredMarginPerCell = 0.3
    params.adaptiveThreshWinSizeMax = 33
    params.minMarkerPerimeterRate = min_perimeter_rate
    params.aprilTagQuadDecimate = decimate
    return params


@lru_cache(maxsize=64)
def _marker_detector(
    refinement: int, dictionaries: tuple[str, ...], min_perimeter_rate: float, decimate: float
) -> cv2.aruco.ArucoDetector:
    detector = cv2.aruco.ArucoDetector(
        get_dictionary(dictionaries[0]), _parameters(refinement, min_perimeter_rate, decimate)
    )
    detector.setDictionaries([get_dictionary(name) for name in dictionaries])
    return detector


#: Marker corners by dictionary and id, each with whether its edge fit passed its check.
_Found = dict[str, dict[int, tuple[Array, bool]]]


def _detect_with(
    gray: npt.NDArray[np.uint8],
    refinement: int,
    dictionaries: tuple[str, ...],
    decimate: float = 0.0,
) -> _Found:
    """One detector pass over every dictionary at once (the candidate quads are found once),
    each marker refined by ``refine_marker_edges``."""
    rate = round(min(0.03, MIN_PERIMETER_PX / max(gray.shape)), 4)
    detector = _marker_detector(refinement, dictionaries, rate, decimate)
    corners, ids, _, which = detector.detectMarkersMultiDict(gray)
    found: _Found = {name: {} for name in dictionaries}
    if ids is None or len(ids) == 0:
        return found
    offset = APRILTAG_PIXEL_OFFSET if refinement == cv2.aruco.CORNER_REFINE_APRILTAG else 0.0
    quads = np.asarray(corners, np.float64).reshape(-1, 4, 2) - offset
    names = [dictionaries[int(k)] for k in np.ravel(which)]
    cells = np.array([marker_cells(name) for name in names], np.float64)
    refined, ok = _refine_edges(gray, quads, cells)
    for quad, good, i, name in zip(refined, ok, np.ravel(ids), names, strict=True):
        found[name][int(i)] = (quad, bool(good))
    return found


def _markers(
    gray: npt.NDArray[np.uint8],
    wanted: set[int],
    dictionaries: tuple[str, ...],
    *,
    thorough: bool = False,
) -> dict[str, dict[int, Array]]:
    """Marker corners (4, 2) by dictionary and id.

    The contour finder first. The AprilTag quad finder then, at full resolution, when the
    first pass found nothing, missed one of the ``wanted`` ids (of the first dictionary) or
    left a marker whose edge fit failed its check; else, when ``thorough``, at half
    resolution (``QUAD_DECIMATE``: 4x faster, and on the rendered tags it added nothing to
    the contour finder's at any resolution, while on the real photos it found the tag turned
    70 degrees at half resolution too). A marker both find keeps the corners whose edge fit
    passed (the first pass's if both did).
    """
    found = _detect_with(gray, cv2.aruco.CORNER_REFINE_NONE, dictionaries)
    doubtful = any(not ok for markers in found.values() for _, ok in markers.values())
    rescue = doubtful or not any(found.values()) or not wanted <= found[dictionaries[0]].keys()
    if rescue or thorough:
        decimate = 0.0 if rescue else QUAD_DECIMATE
        extra = _detect_with(gray, cv2.aruco.CORNER_REFINE_APRILTAG, dictionaries, decimate)
        for name, markers in extra.items():
            for i, (quad, ok) in markers.items():
                if i not in found[name] or (ok and not found[name][i][1]):
                    found[name][i] = (quad, ok)
    for name, markers in found.items():
        for i, (_, ok) in markers.items():
            if not ok:
                log.debug("%s id %d: edge fit failed its check; OpenCV's corners kept", name, i)
    return {name: {i: quad for i, (quad, _) in markers.items()} for name, markers in found.items()}


def _bilinear(gray: npt.NDArray[np.uint8], points: Array) -> tuple[Array, npt.NDArray[np.bool_]]:
    """Gray levels at (..., 2) points (px, pixel centres at integers), bilinear, and whether
    each point lies inside the image (outside ones read the nearest border pixel)."""
    h, w = gray.shape
    x, y = points[..., 0], points[..., 1]
    inside = (x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)
    x = np.clip(np.nan_to_num(x), 0, w - 1.000001)  # NaNs (of a failed fit) read pixel 0
    y = np.clip(np.nan_to_num(y), 0, h - 1.000001)
    x0 = np.floor(x).astype(np.intp)
    y0 = np.floor(y).astype(np.intp)
    fx, fy = x - x0, y - y0
    top = gray[y0, x0] * (1 - fx) + gray[y0, x0 + 1] * fx
    bottom = gray[y0 + 1, x0] * (1 - fx) + gray[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bottom * fy, inside


#: Edge fit: sample rows along each edge and samples across it.
_ALONG, _ACROSS = 32, 21


def refine_marker_edges(gray: npt.NDArray[np.uint8], corners: Array, cells: int) -> Array | None:
    """Subpixel (4, 2) corners (px, pixel centres at integers, same order) of a marker whose
    black square has ``cells`` cells a side (its data cells and the one-cell border), from
    rough ``corners``; None when the fit fails its check (keep the rough corners then).

    OpenCV refines ArUco corners only with ``cornerSubPix`` (a saddle-point search meant for
    chessboard corners, which a tag's outer corner is not: 0.4 px median error on rendered
    tags) or with the contour's own pixels; it has no fit of the tag's edges to the gray
    image, which AprilTag 3 has (``refine_edges``). Here, after AprilTag's: along each of the
    four outer edges, the image is sampled across the edge (bilinear, ``_ACROSS`` samples over
    at most ``EDGE_SEARCH_PX`` either side, and never beyond half a cell inside, where the next
    edge inside the tag may start, nor 0.8 cell outside); the edge point of each sample row is
    the centroid of the rise from black to white, weighted by the cube of its gradient (the
    cube favours the peak over the foot the tag's inner edges add under blur; falling
    gradients, from other edges, count zero). A line is fitted to each edge's points
    (weighted by their gradient) and adjacent lines intersect in the corners. Twice, each
    pass centring its windows on the edges of the last. Rows near the corners are skipped:
    there the adjacent edge's blur bends the profile.

    The check: the corners stay convex and within 1.5 cells (at least 2 px, at most twice
    ``EDGE_SEARCH_PX``) of the rough ones, and the middle of each side's black border is dark
    (``BORDER_WHITENESS``), so a side fitted to a shadow beside the tag is not taken.
    """
    quad = np.asarray(corners, np.float64).reshape(1, 4, 2)
    refined, ok = _refine_edges(gray, quad, np.array([float(cells)]))
    return refined[0] if ok[0] else None


def _refine_edges(
    gray: npt.NDArray[np.uint8], quads: Array, cells: Array
) -> tuple[Array, npt.NDArray[np.bool_]]:
    """``refine_marker_edges`` of (N, 4, 2) ``quads`` at once (N) ``cells``: the (N, 4, 2)
    corners (the rough ones where the fit failed) and whether each fit passed its check."""
    c = quads.copy()
    ok = np.ones(len(quads), bool)
    whiteness = np.zeros((len(quads), 4))
    with np.errstate(all="ignore"):  # failed fits give NaNs, masked by ``ok``
        for _ in range(EDGE_PASSES):
            new, whiteness, valid = _fit_edges(gray, c, cells)
            ok &= valid & np.all(np.isfinite(new), axis=(1, 2))
            c = np.where(ok[:, None, None], new, c)
        side = np.linalg.norm(quads - np.roll(quads, -1, axis=1), axis=2)
        limit = np.clip(1.5 * side.mean(axis=1) / cells, 2.0, 2 * EDGE_SEARCH_PX)
        ok &= np.max(np.linalg.norm(c - quads, axis=2), axis=1) <= limit
        ok &= _turns_alike(c, quads)
        ok &= np.max(whiteness, axis=1) <= BORDER_WHITENESS
    return np.where(ok[:, None, None], c, quads), ok


def _turns_alike(c: Array, quads: Array) -> npt.NDArray[np.bool_]:
    """(N,) True where the quadrilateral ``c`` is convex and turns the way ``quads`` do."""

    def turns(q: Array) -> Array:
        a = np.roll(q, -1, axis=1) - q
        b = np.roll(q, -2, axis=1) - np.roll(q, -1, axis=1)
        return np.asarray(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], np.float64)

    t, t0 = turns(c), turns(quads)
    return np.all(np.sign(t) == np.sign(t0[:, :1]), axis=1) & np.all(t != 0, axis=1)


def _fit_edges(
    gray: npt.NDArray[np.uint8], c: Array, cells: Array
) -> tuple[Array, Array, npt.NDArray[np.bool_]]:
    """One pass of ``refine_marker_edges`` over (N, 4, 2) corners ``c``: the (N, 4, 2)
    corners from the fitted edges, the (N, 4) whiteness of the middle of each side's black
    border (0 the tag's black, 1 the white outside) and whether the (N) fits could be made.
    Edge k runs from corner k to corner k + 1."""
    edge = np.roll(c, -1, axis=1) - c
    length = np.linalg.norm(edge, axis=2)  # (N, 4)
    d = edge / np.maximum(length, 1e-9)[..., None]
    n = np.stack([d[..., 1], -d[..., 0]], axis=-1)
    outwards = np.sum(n * (c + edge / 2 - c.mean(axis=1, keepdims=True)), axis=2)
    n *= np.where(outwards < 0, -1.0, 1.0)[..., None]
    # Cell size across each edge: the distance of the far side's corners from it, over cells.
    far = np.stack([np.roll(c, -2, axis=1), np.roll(c, -3, axis=1)], axis=2)  # (N, 4, 2, 2)
    across = np.abs(np.sum((far - c[:, :, None]) * n[:, :, None], axis=3)).mean(axis=2)
    across /= cells[:, None]
    skip = np.maximum(1.0, 0.5 * length / cells[:, None])
    usable = length - 2 * skip
    valid = np.all((length >= 4) & (usable >= 1) & (across >= 0.75), axis=1)
    t = skip[..., None] + usable[..., None] * np.linspace(0, 1, _ALONG)  # (N, 4, rows)
    inner = np.minimum(0.5 * across, EDGE_SEARCH_PX)
    outer = np.minimum(0.8 * across, EDGE_SEARCH_PX)
    s = -inner[..., None] + (inner + outer)[..., None] * np.linspace(0, 1, _ACROSS)
    base = c[:, :, None] + t[..., None] * d[:, :, None]  # (N, 4, rows, 2)
    pts = base[:, :, :, None] + s[:, :, None, :, None] * n[:, :, None, None]
    level, inside = _bilinear(gray, pts)  # (N, 4, rows, across)
    ok = inside[..., 1:] & inside[..., :-1]
    weight = np.where(ok, np.clip(np.diff(level, axis=3), 0, None), 0.0) ** 3
    total = weight.sum(axis=3)  # (N, 4, rows)
    s_mid = (s[..., 1:] + s[..., :-1]) / 2
    offset = np.sum(weight * s_mid[:, :, None], axis=3) / total
    points = base + offset[..., None] * n[:, :, None]
    good = total > 1e-9
    valid &= np.all(np.count_nonzero(good, axis=2) >= 3, axis=1)
    # Weighted line fit per edge: the row's summed gradient (back to grey levels) weighs it.
    w = np.where(good, np.cbrt(total), 0.0)
    points = np.where(good[..., None], points, 0.0)
    centre = np.sum(w[..., None] * points, axis=2) / w.sum(axis=2)[..., None]  # (N, 4, 2)
    q = np.where(good[..., None], points - centre[:, :, None], 0.0)
    sxx = np.sum(w * q[..., 0] ** 2, axis=2)
    syy = np.sum(w * q[..., 1] ** 2, axis=2)
    sxy = np.sum(w * q[..., 0] * q[..., 1], axis=2)
    angle = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # of the principal axis
    normal = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
    line = np.concatenate([normal, -np.sum(normal * centre, axis=2, keepdims=True)], axis=2)
    # Corner k joins edge k - 1 and edge k; with unit normals the third component of the
    # cross product is the sine of the angle between the edges.
    meet = np.cross(np.roll(line, 1, axis=1), line)
    valid &= np.all(np.abs(meet[..., 2]) > 1e-3, axis=1)
    corners = meet[..., :2] / meet[..., 2:]
    # Whiteness of each side's black border, half a cell in, between the tag's black (the
    # darkest tenth of its inside: the border and its black data cells) and the white outside.
    dark, _ = _bilinear(gray, base - (0.5 * across)[..., None, None] * n[:, :, None])
    light, _ = _bilinear(gray, base + outer[..., None, None] * n[:, :, None])
    a, b = np.meshgrid(np.linspace(0.1, 0.9, 8), np.linspace(0.1, 0.9, 8))
    a, b = a.ravel()[None, :, None], b.ravel()[None, :, None]
    top = c[:, None, 0] + a * (c[:, None, 1] - c[:, None, 0])
    bottom = c[:, None, 3] + a * (c[:, None, 2] - c[:, None, 3])
    inside_level, _ = _bilinear(gray, top + b * (bottom - top))  # (N, 64)
    black = np.percentile(inside_level, 10, axis=1)[:, None]
    white = np.median(light.reshape(len(c), -1), axis=1)[:, None]
    whiteness = (np.median(dark, axis=2) - black) / np.maximum(white - black, 1.0)
    return corners, whiteness, valid


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
    markers = _markers(gray, own, (target.dictionary,))[target.dictionary]
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
    pixel centres at integers) by id. Both finders run (see the module's docstring)."""
    name = dictionary_name(dictionary)
    return _markers(to_gray(image), set(), (name,), thorough=True)[name]


def markers_by_dictionary(
    image: npt.NDArray[np.uint8], dictionaries: Iterable[str] | None = None
) -> dict[str, dict[int, Array]]:
    """Markers in ``image`` (gray or RGB uint8) of every dictionary in ``dictionaries`` (any
    names ``targets.dictionary_name`` reads; all of ``targets.DICTIONARIES`` by default), for
    telling a user which dictionary a target is printed from: ``{name: {id: (4, 2) corners}}``
    with only the dictionaries that have markers here, most plausible first
    (``by_plausibility``): the first entry is the one to suggest.

    Dictionaries overlap, so one printout shows up under several names: the first N markers
    of ``DICT_6X6_1000`` are ``DICT_6X6_250``'s (and ``_100``'s, ``_50``'s); and clutter, or a
    marker of another family, decodes now and then as a marker of a dictionary whose codes
    lie close together (measured on 41 images of tag36h11 tags and random clutter: 8 such
    markers, of DICT_ARUCO_ORIGINAL, DICT_4X4_*, DICT_APRILTAG_16h5). All are returned.
    """
    names = tuple(
        dict.fromkeys(
            DICTIONARIES if dictionaries is None else (dictionary_name(d) for d in dictionaries)
        )
    )
    if not names:
        raise CalibrationError("markers_by_dictionary needs at least one dictionary name")
    found = _markers(to_gray(image), set(), names, thorough=True)
    hits = {name: markers for name, markers in found.items() if markers}
    return {name: hits[name] for name in by_plausibility({n: len(m) for n, m in hits.items()})}


def by_plausibility(counts: dict[str, int]) -> list[str]:
    """Dictionary names ordered by how likely the markers seen are really theirs, given how
    many markers each has here (``counts``): most markers first; on ties, the dictionary
    whose codes lie furthest apart (most correctable bits: the least prone to false markers,
    so a tag36h11 tag beats a stray 16h5 or 4x4 decode), then the one with fewer ids (within
    a family, ``DICT_6X6_50`` before ``DICT_6X6_250`` when the ids seen fit both), then by
    name."""
    return sorted(
        counts,
        key=lambda n: (
            -counts[n],
            -int(get_dictionary(n).maxCorrectionBits),
            dictionary_size(n),
            n,
        ),
    )
