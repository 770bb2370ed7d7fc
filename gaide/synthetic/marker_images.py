"""Synthetic camera images of markers with their true corners, for detector tests and the
``bench_detector`` benchmark.

A pinhole camera (no distortion) sees targets (``calibration.targets``) lying on the plane
z = 0 of their frames. Each texture is warped by its exact homography into a supersampled
canvas (bilinear), then averaged down ``SUPERSAMPLE`` x ``SUPERSAMPLE`` (INTER_AREA, like a
sensor's pixel area), blurred and given pixel noise. Pixel centres are at integers.

True corners: the tag's black-square corners projected with K. A single tag's texture is
painted at a whole number of texture pixels per cell (``_tag_px_per_m``), so its painted edges
lie exactly on the black square (the texture painter snaps edges to its pixel grid, which
would otherwise move them by up to half a texture pixel).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from calibration.targets import (
    Charuco,
    SingleTag,
    TagGrid,
    Target,
    dictionary_size,
    marker_cells,
)
from gaide_core.errors import ConfigError
from gaide_core.transforms import apply, from_xyz_rpy, make_transform
from gaide_core.types import Array

Image = npt.NDArray[np.uint8]

#: Camera pixels are averaged from SUPERSAMPLE x SUPERSAMPLE samples.
SUPERSAMPLE = 4
#: Texture pixels per supersample at the target's nearest point (finer: less aliasing).
TEXTURE_OVERSAMPLE = 1.5


def camera_matrix(width: int = 640, height: int = 480, f: float = 600.0) -> Array:
    """(3, 3) K (px) of a pinhole camera with its principal point at the image centre."""
    return np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])


def project(K: Array, T_cam_target: Array, points: Array) -> Array:
    """(N, 2) pixels of (N, 3) target-frame points (m)."""
    p = apply(T_cam_target, np.asarray(points, np.float64)) @ K.T
    return np.asarray(p[:, :2] / p[:, 2:3], np.float64)


def tag_corners(tag: SingleTag, K: Array, T_cam_tag: Array) -> Array:
    """(4, 2) true pixels of a tag's black-square corners, OpenCV's order TL, TR, BR, BL."""
    return project(K, T_cam_tag, tag.marker_corners(tag.tag_id))


def facing_camera(xyz: npt.ArrayLike, rpy: npt.ArrayLike, viewed_from_z: float) -> Array:
    """``T_cam_target`` with the target's origin at ``xyz`` (m, camera frame), facing the
    camera from the side its texture is read on, then turned by ``rpy`` (rad)."""
    # Readable from +z (a single tag): z towards -z_cam and y up (-y_cam); boards, read
    # from -z: z along +z_cam and y down.
    R0 = np.diag([1.0, -1.0, -1.0]) if viewed_from_z > 0 else np.eye(3)
    return make_transform(R0, np.asarray(xyz, float)) @ from_xyz_rpy([0, 0, 0], rpy)


def centred(target: Target, T_cam_target: Array) -> Array:
    """``T_cam_target`` moved so that the middle of the target's texture, not its frame's
    origin, sits where ``T_cam_target`` puts the origin (boards have theirs at a corner)."""
    x0, x1, y0, y1 = target.texture(200.0).extent
    return T_cam_target @ make_transform(None, -np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0]))


@dataclass(frozen=True, kw_only=True)
class Look:
    """How a rendered image looks: Gaussian ``blur`` sigma (px), pixel ``noise`` sigma
    (grey levels), and the grey levels of the markers' ``black`` and ``white``."""

    blur: float = 0.6  # px
    noise: float = 2.0  # grey levels
    black: float = 20.0  # grey level
    white: float = 235.0  # grey level

    def __post_init__(self) -> None:
        if self.blur < 0 or self.noise < 0 or not 0 <= self.black < self.white <= 255:
            raise ConfigError(f"bad look {self}: blur, noise >= 0, 0 <= black < white <= 255")


def _tag_px_per_m(tag: SingleTag, px_per_m: float) -> float:
    """The nearest texture scale at or above ``px_per_m`` with a whole number of texture
    pixels per cell (so the painted square is exact)."""
    cell = tag.size / marker_cells(tag.dictionary)
    return math.ceil(px_per_m * cell) / cell


def render(
    placements: Sequence[tuple[Target, Array]],
    K: Array,
    rng: np.random.Generator,
    *,
    size: tuple[int, int] = (640, 480),
    look: Look | None = None,
) -> Image:
    """(H, W) gray uint8 image of targets, each at its ``T_cam_target`` (camera optical
    frame, m), painted in order over a smooth random background."""
    look = look or Look()
    w, h = size
    s = SUPERSAMPLE
    # Supersampled camera: pixel centre u maps to s * u + (s - 1) / 2.
    S = np.array([[s, 0, (s - 1) / 2], [0, s, (s - 1) / 2], [0, 0, 1.0]])
    coarse = rng.uniform(70, 190, (h // 24 + 2, w // 24 + 2)).astype(np.float32)
    canvas = np.asarray(
        cv2.resize(coarse, (w * s, h * s), interpolation=cv2.INTER_CUBIC), np.float32
    )
    for target, T in placements:
        _paint_target(canvas, target, T, S @ K, look)
    img = np.asarray(cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA), np.float64)
    if look.blur > 0:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), look.blur), np.float64)
    img = img + rng.normal(0.0, look.noise, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _paint_target(
    canvas: npt.NDArray[np.float32], target: Target, T: Array, KS: Array, look: Look
) -> None:
    """Warp ``target``'s texture into the supersampled ``canvas`` (in place), only over the
    bounding box of its projection."""
    depth = apply(T, _outline(target, 2000.0))[:, 2]
    if np.any(depth <= 0):
        raise ConfigError("a rendered target must lie wholly in front of the camera")
    px_per_m = TEXTURE_OVERSAMPLE * KS[0, 0] / float(depth.min())
    if isinstance(target, SingleTag):
        px_per_m = _tag_px_per_m(target, px_per_m)
    tex = target.texture(px_per_m)
    x_min, _, _, y_max = tex.extent
    quad = _outline(target, px_per_m)
    # Texture pixel (c, r) -> target-frame (x, y, 1), from TargetTexture's convention.
    A = np.array(
        [
            [1 / px_per_m, 0, x_min + 0.5 / px_per_m],
            [0, -1 / px_per_m, y_max - 0.5 / px_per_m],
            [0, 0, 1],
        ]
    )
    Rt = np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])
    H = KS @ Rt @ A
    uv = project(KS, T, quad)
    hh, ww = canvas.shape
    u0 = max(int(np.floor(uv[:, 0].min())) - 2, 0)
    v0 = max(int(np.floor(uv[:, 1].min())) - 2, 0)
    u1 = min(int(np.ceil(uv[:, 0].max())) + 3, ww)
    v1 = min(int(np.ceil(uv[:, 1].max())) + 3, hh)
    if u1 <= u0 or v1 <= v0:
        return
    shift = np.array([[1.0, 0, -u0], [0, 1.0, -v0], [0, 0, 1.0]])
    levels = look.black + tex.image.astype(np.float32) * ((look.white - look.black) / 255.0)
    box = (u1 - u0, v1 - v0)
    warped = cv2.warpPerspective(
        levels, shift @ H, box, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    # Coverage of each sample by the texture, so its outline is blended, not a dark seam.
    cover = cv2.warpPerspective(
        np.ones_like(levels), shift @ H, box, flags=cv2.INTER_LINEAR, borderValue=0.0
    )
    roi = canvas[v0:v1, u0:u1]
    roi += cover * (warped - roi)


@dataclass(frozen=True, eq=False)
class TagCase:
    """One rendered image of single tags: ``kind`` of case, (H, W) gray ``image``, the
    camera ``K`` (3, 3) and each tag's true (4, 2) corners (px, TL, TR, BR, BL) by id."""

    kind: str
    image: Image
    K: Array
    corners: dict[int, Array]


@dataclass(frozen=True)
class _Kind:
    """How the tags of one case kind are drawn: width (px, face-on), tilt (degrees), blur
    (px) and noise (grey levels) ranges, tags per image, and whether one touches the border."""

    width: tuple[float, float]
    tilt: tuple[float, float] = (0.0, 35.0)
    blur: tuple[float, float] = (0.4, 0.8)
    noise: tuple[float, float] = (1.0, 3.0)
    tags: tuple[int, int] = (1, 1)
    edge: bool = False


#: The kinds of ``tag_cases``: small (15-25 px wide), far (small, turned and a little soft),
#: tilted (60-70 degrees), blurred, edge (a corner 0.5-2.5 px from the image border),
#: multi (3-6 tags in one image), noisy.
CASE_KINDS: dict[str, _Kind] = {
    "small": _Kind(width=(15, 25), tilt=(0, 25)),
    "far": _Kind(width=(18, 28), tilt=(25, 45), blur=(0.8, 1.1)),
    "tilted": _Kind(width=(45, 90), tilt=(60, 70)),
    "blurred": _Kind(width=(25, 50), blur=(1.2, 2.0)),
    "edge": _Kind(width=(25, 60), edge=True),
    "multi": _Kind(width=(18, 60), tilt=(0, 45), tags=(3, 6)),
    "noisy": _Kind(width=(20, 45), noise=(6.0, 10.0)),
}
#: Edge (m) of the tags of ``tag_cases``.
TAG_SIZE = 0.08
#: Quiet zone kept inside the image (px) by all but the edge cases.
_MARGIN = 3.0


def tag_cases(
    seed: int = 0, per_kind: int = 8, size: tuple[int, int] = (640, 480)
) -> list[TagCase]:
    """``per_kind`` seeded images of each of ``CASE_KINDS``: tag36h11 tags ``TAG_SIZE`` wide
    seen by a camera of 600 px focal length, on a smooth random background, their black and
    white grey levels drawn from 10-50 and 170-245."""
    rng = np.random.default_rng(seed)
    K = camera_matrix(*size)
    cases: list[TagCase] = []
    for name, kind in CASE_KINDS.items():
        for _ in range(per_kind):
            look = Look(
                blur=rng.uniform(*kind.blur),
                noise=rng.uniform(*kind.noise),
                black=rng.uniform(10, 50),
                white=rng.uniform(170, 245),
            )
            n_tags = int(rng.integers(kind.tags[0], kind.tags[1] + 1))
            tags = [SingleTag(int(i), TAG_SIZE) for i in rng.choice(587, n_tags, replace=False)]
            placed: list[tuple[SingleTag, Array]] = []
            boxes: list[Array] = []
            for tag in tags:
                for _ in range(100):  # tags of one image do not overlap
                    T = _place(tag, K, rng, kind, size)
                    uv = project(K, T, _outline(tag, 2000.0))
                    box = np.array([*uv.min(axis=0), *uv.max(axis=0)])
                    if all(_apart(box, b) for b in boxes):
                        break
                boxes.append(box)
                placed.append((tag, T))
            image = render(list(placed), K, rng, size=size, look=look)
            corners = {tag.tag_id: tag_corners(tag, K, T) for tag, T in placed}
            cases.append(TagCase(name, image, K, corners))
    return cases


def _apart(a: Array, b: Array) -> bool:
    """True when boxes (u0, v0, u1, v1) do not overlap."""
    return bool(a[0] > b[2] or a[2] < b[0] or a[1] > b[3] or a[3] < b[1])


def _tilt(rng: np.random.Generator, lo_deg: float, hi_deg: float) -> Array:
    """(3, 3) turn by lo..hi degrees about a random axis in the tag's plane, after a random
    spin about its normal."""
    phi = rng.uniform(0, 2 * np.pi)
    axis = np.array([np.cos(phi), np.sin(phi), 0.0])
    tilt = Rotation.from_rotvec(axis * np.radians(rng.uniform(lo_deg, hi_deg)))
    spin = Rotation.from_rotvec([0, 0, rng.uniform(-np.pi, np.pi)])
    return np.asarray((tilt * spin).as_matrix(), np.float64)


def _place(
    tag: SingleTag, K: Array, rng: np.random.Generator, kind: _Kind, size: tuple[int, int]
) -> Array:
    """``T_cam_tag`` of a tag ``kind.width`` px wide face-on, turned by ``kind.tilt``, with
    its quiet zone ``_MARGIN`` px inside the image, or with a corner at the border
    (``kind.edge``)."""
    w, h = size
    margin = 0.0 if kind.edge else _MARGIN
    quiet = _outline(tag, 2000.0)
    for _ in range(200):
        z = K[0, 0] * tag.size / rng.uniform(*kind.width)
        xyz = z * np.linalg.solve(K, [rng.uniform(0, w - 1), rng.uniform(0, h - 1), 1.0])
        R = _tilt(rng, *kind.tilt)
        T = facing_camera(xyz, [0, 0, 0], 1.0) @ make_transform(R, None)
        if np.any(apply(T, quiet)[:, 2] <= 0.05):
            continue
        uv = project(K, T, quiet)
        if uv.min() >= margin and np.all(uv.max(axis=0) <= [w - 1 - margin, h - 1 - margin]):
            return _to_border(tag, K, T, rng, size) if kind.edge else T
    raise ConfigError(f"no pose found for a {kind.width} px tag in a {w}x{h} image")


def _to_border(
    tag: SingleTag, K: Array, T: Array, rng: np.random.Generator, size: tuple[int, int]
) -> Array:
    """``T`` slid sideways (along the camera's x or y) until the tag's outermost corner on a
    random side is 0.5-2.5 px from the image border (the tag stays wholly inside)."""
    w, h = size
    side = int(rng.integers(4))  # left, top, right, bottom
    gap = rng.uniform(0.5, 2.5)
    axis = side % 2  # 0: u, 1: v
    T = T.copy()
    corners = tag.marker_corners(tag.tag_id)
    for _ in range(6):  # Newton steps: a shift moves near and far corners differently
        uv = tag_corners(tag, K, T)
        depth = apply(T, corners)[:, 2]
        i = int(np.argmin(uv[:, axis]) if side < 2 else np.argmax(uv[:, axis]))
        goal = gap if side < 2 else (w, h)[axis] - 1 - gap
        T[axis, 3] += (goal - uv[i, axis]) * depth[i] / K[axis, axis]
    return T


def _outline(target: Target, px_per_m: float) -> Array:
    """(4, 3) corners (m, target frame) of the target's texture painted at ``px_per_m``,
    quiet zone included."""
    x0, x1, y0, y1 = target.texture(px_per_m).extent
    return np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], np.float64)


@dataclass(frozen=True, eq=False)
class TargetCase:
    """One rendered image of one ``target`` (of ``target.dictionary``): (H, W) gray
    ``image`` seen by a camera ``K`` (3, 3) at ``T_cam_target`` (4, 4)."""

    target: Target
    image: Image
    K: Array
    T_cam_target: Array


def dictionary_targets(dictionary: str) -> list[Target]:
    """A single tag (6 cm), a 3 x 2 grid (3.5 cm markers) and a 5 x 4 ChArUco board (3.5 cm
    squares) of ``dictionary`` (smaller boards where it has too few ids)."""
    ids = dictionary_size(dictionary)
    grid = (3, 2) if ids >= 6 else (2, 2)
    board = (5, 4) if ids >= 10 else (4, 3)
    return [
        SingleTag(min(7, ids - 1), 0.06, dictionary),
        TagGrid(*grid, 0.035, 0.01, 0, dictionary),
        Charuco(*board, 0.035, 0.026, dictionary),
    ]


def target_cases(
    dictionaries: Sequence[str], seed: int = 0, poses: int = 2, size: tuple[int, int] = (640, 480)
) -> list[TargetCase]:
    """``poses`` seeded images of each of ``dictionary_targets`` of each dictionary: the
    target 0.3-0.5 m away, turned up to 40 degrees, anywhere it fits in the image."""
    rng = np.random.default_rng(seed)
    K = camera_matrix(*size)
    w, h = size
    cases: list[TargetCase] = []
    for name in dictionaries:
        for target in dictionary_targets(name):
            tex = target.texture(1000.0)
            for _ in range(poses):
                for _ in range(200):
                    xyz = [
                        rng.uniform(-0.08, 0.08),
                        rng.uniform(-0.06, 0.06),
                        rng.uniform(0.3, 0.5),
                    ]
                    T = centred(target, facing_camera(xyz, [0, 0, 0], tex.viewed_from_z))
                    T = T @ make_transform(_tilt(rng, 0, 40), None)
                    uv = project(K, T, _outline(target, 2000.0))
                    if uv.min() >= _MARGIN and np.all(uv.max(axis=0) <= [w - 4, h - 4]):
                        break
                look = Look(blur=rng.uniform(0.4, 0.9), noise=rng.uniform(1.0, 3.0))
                cases.append(TargetCase(target, render([(target, T)], K, rng, look=look), K, T))
    return cases
