"""Calibration targets: their specs, frames, points and printable textures.

Markers come from any of OpenCV's predefined dictionaries (``DICTIONARIES``: the ArUco
``DICT_4X4_*`` ... ``DICT_7X7_*``, ``DICT_ARUCO_ORIGINAL``, ``DICT_ARUCO_MIP_36h12`` and the
AprilTag families ``DICT_APRILTAG_16h5/25h9/36h10/36h11``); tag36h11 is the default. Three
kinds, all frozen dataclasses, lengths in metres:

- ``SingleTag``: one tag. Target frame: origin at the tag centre, x right, y up,
  z out of the tag towards the viewer (the object-point convention of OpenCV's
  ``SOLVEPNP_IPPE_SQUARE``). ``size`` is the edge of the black square (the data cells plus the one-cell
  black border: 8 cells for tag36h11, 6 for DICT_4X4_*).
- ``TagGrid``: an OpenCV ``GridBoard`` of tags. Target frame: OpenCV's board frame, origin at
  the top-left corner of the top-left marker (as the printout is read), x right along the
  first row, y *down* the columns, z *into* the board (away from the viewer).
- ``Charuco``: an OpenCV ``CharucoBoard``. Target frame: OpenCV's board frame, origin at the
  outer top-left corner of the chessboard, x right, y down, z into the board.

A target's ``texture(px_per_m)`` paints it for a renderer: pixel (row r, col c) has its
centre at ``x = x_min + (c + 0.5) / px_per_m``, ``y = y_max - (r + 0.5) / px_per_m``,
``z = 0`` in the target frame. For the boards, whose y points down, the image array is
therefore upside down compared with a printout; painted with that convention it reads
correctly from the side the camera must be on (``TargetTexture.viewed_from_z``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from gaide_core.errors import CalibrationError
from gaide_core.types import Array

#: OpenCV's predefined dictionaries by canonical name.
DICTIONARIES: dict[str, int] = {
    **{
        f"DICT_{n}X{n}_{count}": getattr(cv2.aruco, f"DICT_{n}X{n}_{count}")
        for n in (4, 5, 6, 7)
        for count in (50, 100, 250, 1000)
    },
    "DICT_ARUCO_ORIGINAL": cv2.aruco.DICT_ARUCO_ORIGINAL,
    "DICT_ARUCO_MIP_36h12": cv2.aruco.DICT_ARUCO_MIP_36h12,
    "DICT_APRILTAG_16h5": cv2.aruco.DICT_APRILTAG_16h5,
    "DICT_APRILTAG_25h9": cv2.aruco.DICT_APRILTAG_25h9,
    "DICT_APRILTAG_36h10": cv2.aruco.DICT_APRILTAG_36h10,
    "DICT_APRILTAG_36h11": cv2.aruco.DICT_APRILTAG_36h11,
}
#: The dictionary of a target spec without ``dict=``.
DEFAULT_DICTIONARY = "DICT_APRILTAG_36h11"
_BY_KEY = {name.lower().removeprefix("dict_"): name for name in DICTIONARIES}
_BY_KEY.update(
    {
        name.lower().removeprefix("dict_apriltag_"): name
        for name in DICTIONARIES
        if "APRILTAG" in name
    }
)
_BY_KEY.update({"aruco_original": "DICT_ARUCO_ORIGINAL", "original": "DICT_ARUCO_ORIGINAL"})


def dictionary_name(text: str) -> str:
    """Canonical dictionary name from a user's spelling: ``DICT_6X6_250``, ``6x6_250``,
    ``tag36h11``, ``apriltag_36h11``, ``aruco_original`` (case-insensitive)."""
    key = text.strip().lower().removeprefix("dict_")
    key = key.removeprefix("tag") if re.fullmatch(r"tag\d+h\d+", key) else key
    name = _BY_KEY.get(key) or _BY_KEY.get(key.removeprefix("apriltag_"))
    if name is None:
        raise CalibrationError(
            f"unknown marker dictionary {text!r}; valid: {', '.join(DICTIONARIES)}"
        )
    return name


def short_name(dictionary: str) -> str:
    """The name people use: ``tag36h11`` for the AprilTag families, else OpenCV's."""
    if dictionary.startswith("DICT_APRILTAG_"):
        return "tag" + dictionary.removeprefix("DICT_APRILTAG_")
    return dictionary


@lru_cache(maxsize=64)
def get_dictionary(name: str = DEFAULT_DICTIONARY) -> cv2.aruco.Dictionary:
    """OpenCV's predefined dictionary ``name`` (any spelling ``dictionary_name`` reads)."""
    return cv2.aruco.getPredefinedDictionary(DICTIONARIES[dictionary_name(name)])


def dictionary_size(name: str) -> int:
    """Number of distinct marker ids in a dictionary."""
    return int(get_dictionary(name).bytesList.shape[0])


def marker_cells(name: str) -> int:
    """Cells along a marker's black square: its data cells plus the one-cell border."""
    return int(get_dictionary(name).markerSize) + 2


def aruco_dictionary() -> cv2.aruco.Dictionary:
    """OpenCV's tag36h11 dictionary (``DICT_APRILTAG_36h11``), the default."""
    return get_dictionary(DEFAULT_DICTIONARY)


#: Number of distinct ids in the tag36h11 family.
TAG36H11_IDS = 587
#: Cells along a tag36h11 tag's black square: 6 data cells and a one-cell black border.
TAG_CELLS = 8


def _tag_bits(tag_id: int, dictionary: str = DEFAULT_DICTIONARY) -> npt.NDArray[np.uint8]:
    """(n, n) cells of a marker (n = ``marker_cells``), 0 black / 255 white, row 0 at the
    marker's top."""
    n = marker_cells(dictionary)
    bits = cv2.aruco.generateImageMarker(get_dictionary(dictionary), tag_id, n, borderBits=1)
    return np.asarray(bits, np.uint8)


@dataclass(frozen=True)
class TargetTexture:
    """A target painted as a grayscale image for a renderer.

    ``image``: (H, W) uint8, white quiet zone included. ``extent``: ``(x_min, x_max, y_min,
    y_max)`` (m) in the target frame, with ``W = (x_max - x_min) * px_per_m`` and likewise H.
    Pixel (r, c) centre <-> ``(x_min + (c + 0.5) / px_per_m, y_max - (r + 0.5) / px_per_m, 0)``.
    ``viewed_from_z``: +1 if the camera must be on the target frame's +z side to read the
    texture (single tag), -1 for the boards (their z points away from the viewer).
    """

    image: npt.NDArray[np.uint8]
    extent: tuple[float, float, float, float]
    px_per_m: float
    viewed_from_z: float


#: A block of tag cells to paint: top-left corner (x, y) (m, target frame, as the printout
#: is read), cells (n, n) uint8 with row 0 at the printout's top, edge length of the block (m).
Square = tuple[tuple[float, float], npt.NDArray[np.uint8], float]


def _paint(
    px_per_m: float,
    bounds: tuple[float, float, float, float],
    squares: list[Square],
    *,
    y_down: bool,
    viewed_from_z: float,
) -> TargetTexture:
    """Paint blocks of cells onto a white texture covering ``bounds`` (x0, x1, y0, y1) (m).

    ``y_down``: the target's y axis points down the printout (boards) rather than up (single
    tag). Each texture pixel takes the cell under its centre (nearest sampling: edges are
    exact to half a pixel, with no blur).
    """
    if not (math.isfinite(px_per_m) and px_per_m > 0):
        raise CalibrationError(f"texture px_per_m must be a positive number, got {px_per_m}")
    x_min, x_max, y_min, y_max = bounds
    width = max(1, round((x_max - x_min) * px_per_m))
    height = max(1, round((y_max - y_min) * px_per_m))
    if width * height > 64_000_000:
        raise CalibrationError(
            f"a {width}x{height} px texture is too large: use a px_per_m below {px_per_m}"
        )
    # Keep the pixel convention exact: the extent follows the whole number of pixels.
    x_max = x_min + width / px_per_m
    y_min = y_max - height / px_per_m
    xs = x_min + (np.arange(width) + 0.5) / px_per_m
    ys = y_max - (np.arange(height) + 0.5) / px_per_m
    image = np.full((height, width), 255, np.uint8)
    for (cx, cy), cells, edge in squares:
        n = cells.shape[0]
        cols = np.floor((xs - cx) / (edge / n)).astype(int)
        down = (ys - cy) if y_down else (cy - ys)
        rows = np.floor(down / (edge / n)).astype(int)
        ci = np.nonzero((cols >= 0) & (cols < n))[0]
        ri = np.nonzero((rows >= 0) & (rows < n))[0]
        if ci.size and ri.size:
            image[np.ix_(ri, ci)] = cells[np.ix_(rows[ri], cols[ci])]
    return TargetTexture(image, (x_min, x_max, y_min, y_max), px_per_m, viewed_from_z)


def _check_length(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise CalibrationError(f"{name} must be a positive length in metres, got {value!r}")


def _check_count(name: str, value: int, minimum: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise CalibrationError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _check_ids(first: int, count: int, dictionary: str) -> None:
    size = dictionary_size(dictionary)
    if first < 0 or first + count > size:
        raise CalibrationError(
            f"tag ids {first}..{first + count - 1} do not exist: {short_name(dictionary)} has "
            f"ids 0..{size - 1}"
        )


def _dict_field(dictionary: str) -> str:
    """The spec's ``,dict=...`` suffix, empty for the default dictionary."""
    return "" if dictionary == DEFAULT_DICTIONARY else f",dict={dictionary}"


def _check_dictionary(obj: object, dictionary: str) -> None:
    object.__setattr__(obj, "dictionary", dictionary_name(dictionary))


@dataclass(frozen=True)
class SingleTag:
    """One tag of ``dictionary``; ``size`` (m) is the edge of its black square.

    Frame: origin at the tag centre, x right, y up, z towards the viewer.
    """

    tag_id: int
    size: float  # m, black-square edge
    dictionary: str = DEFAULT_DICTIONARY

    def __post_init__(self) -> None:
        _check_dictionary(self, self.dictionary)
        _check_count("tag_id", self.tag_id, 0)
        _check_ids(self.tag_id, 1, self.dictionary)
        _check_length("tag size", self.size)

    @property
    def ids(self) -> tuple[int, ...]:
        """Tag ids that belong to the target."""
        return (self.tag_id,)

    def marker_corners(self, tag_id: int) -> Array:
        """(4, 3) corners (m, target frame) of a tag in OpenCV's order TL, TR, BR, BL."""
        h = self.size / 2
        return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])

    def describe(self) -> str:
        """Human wording for messages: ``tag36h11 tag id 3 (0.08 m)``."""
        return f"{short_name(self.dictionary)} tag id {self.tag_id} ({self.size:g} m)"

    def spec(self) -> str:
        """The CLI string that ``parse_target`` reads back to this target."""
        if self.dictionary == DEFAULT_DICTIONARY:
            return f"tag36h11:id={self.tag_id},size={self.size!r}"
        return f"tag:id={self.tag_id},size={self.size!r},dict={self.dictionary}"

    def scaled(self, factor: float) -> SingleTag:
        """The same tag with every length times ``factor``."""
        return SingleTag(self.tag_id, self.size * factor, self.dictionary)

    def to_dict(self) -> dict[str, Any]:
        """YAML-ready mapping (see the module function ``to_dict``)."""
        return to_dict(self)

    def size_text(self) -> str:
        return f"tag size {self.size:.3g} m"

    def texture(self, px_per_m: float) -> TargetTexture:
        """The tag with a white quiet zone of two cells, see ``TargetTexture``."""
        h = self.size / 2
        margin = 2 * self.size / marker_cells(self.dictionary)
        square: Square = ((-h, h), _tag_bits(self.tag_id, self.dictionary), self.size)
        bounds = (-h - margin, h + margin, -h - margin, h + margin)
        return _paint(px_per_m, bounds, [square], y_down=False, viewed_from_z=1.0)


class _Board:
    """Shared behaviour of the OpenCV boards (y down, z into the board)."""

    board: cv2.aruco.Board
    dictionary: str

    @cached_property
    def _points(self) -> dict[int, Array]:
        ids = np.asarray(self.board.getIds()).ravel()
        pts = [np.asarray(p, np.float64).reshape(4, 3) for p in self.board.getObjPoints()]
        return {int(i): p for i, p in zip(ids, pts, strict=True)}

    @property
    def ids(self) -> tuple[int, ...]:
        """Tag ids that belong to the target."""
        return tuple(self._points)

    def marker_corners(self, tag_id: int) -> Array:
        """(4, 3) corners (m, board frame) of one marker, OpenCV's order TL, TR, BR, BL."""
        return self._points[tag_id].copy()

    def _marker_squares(self) -> list[Square]:
        squares: list[Square] = []
        for tag_id, pts in self._points.items():
            edge = float(pts[1, 0] - pts[0, 0])
            bits = _tag_bits(tag_id, self.dictionary)
            squares.append(((float(pts[0, 0]), float(pts[0, 1])), bits, edge))
        return squares


@dataclass(frozen=True)
class TagGrid(_Board):
    """A grid of ``markers_x`` x ``markers_y`` tags of ``dictionary`` (OpenCV ``GridBoard``).

    ``marker_size`` (m): black-square edge; ``separation`` (m): gap between markers; ids run
    from ``first_id`` along rows. Frame: OpenCV's board frame (origin top-left, y down, z
    into the board).
    """

    markers_x: int
    markers_y: int
    marker_size: float  # m
    separation: float  # m
    first_id: int = 0
    dictionary: str = DEFAULT_DICTIONARY

    def __post_init__(self) -> None:
        _check_dictionary(self, self.dictionary)
        _check_count("markers_x", self.markers_x, 1)
        _check_count("markers_y", self.markers_y, 1)
        _check_count("first_id", self.first_id, 0)
        _check_ids(self.first_id, self.markers_x * self.markers_y, self.dictionary)
        _check_length("marker size", self.marker_size)
        _check_length("separation", self.separation)

    @cached_property
    def board(self) -> cv2.aruco.Board:  # type: ignore[override]
        ids = np.arange(self.first_id, self.first_id + self.markers_x * self.markers_y)
        return cv2.aruco.GridBoard(
            (self.markers_x, self.markers_y),
            self.marker_size,
            self.separation,
            get_dictionary(self.dictionary),
            ids.astype(np.int32),
        )

    def describe(self) -> str:
        return (
            f"{self.markers_x}x{self.markers_y} {short_name(self.dictionary)} grid, ids "
            f"{self.first_id}..{self.first_id + self.markers_x * self.markers_y - 1}"
        )

    def spec(self) -> str:
        return (
            f"grid:{self.markers_x}x{self.markers_y},marker={self.marker_size!r},"
            f"sep={self.separation!r},first={self.first_id}{_dict_field(self.dictionary)}"
        )

    def scaled(self, factor: float) -> TagGrid:
        return TagGrid(
            self.markers_x,
            self.markers_y,
            self.marker_size * factor,
            self.separation * factor,
            self.first_id,
            self.dictionary,
        )

    def to_dict(self) -> dict[str, Any]:
        """YAML-ready mapping (see the module function ``to_dict``)."""
        return to_dict(self)

    def size_text(self) -> str:
        return f"marker size {self.marker_size:.3g} m (separation {self.separation:.3g} m)"

    def texture(self, px_per_m: float) -> TargetTexture:
        """The grid with a white quiet zone of a quarter marker, see ``TargetTexture``."""
        width = self.markers_x * self.marker_size + (self.markers_x - 1) * self.separation
        height = self.markers_y * self.marker_size + (self.markers_y - 1) * self.separation
        m = max(self.marker_size / 4, self.separation)
        bounds = (-m, width + m, -m, height + m)
        return _paint(px_per_m, bounds, self._marker_squares(), y_down=True, viewed_from_z=-1.0)


@dataclass(frozen=True)
class Charuco(_Board):
    """A ChArUco board of ``squares_x`` x ``squares_y`` squares (OpenCV ``CharucoBoard``).

    ``square_size`` (m): chessboard square edge; ``marker_size`` (m): tag black-square edge
    inside the white squares; tag ids from 0, from ``dictionary``. ``legacy``: OpenCV's
    pattern before 4.6. Frame: OpenCV's board frame (origin at the outer top-left corner, y
    down, z into the board). Its points are the inner chessboard corners.
    """

    squares_x: int
    squares_y: int
    square_size: float  # m
    marker_size: float  # m
    dictionary: str = DEFAULT_DICTIONARY
    legacy: bool = False

    def __post_init__(self) -> None:
        _check_dictionary(self, self.dictionary)
        _check_count("squares_x", self.squares_x, 2)
        _check_count("squares_y", self.squares_y, 2)
        _check_length("square size", self.square_size)
        _check_length("marker size", self.marker_size)
        if self.marker_size >= self.square_size:
            raise CalibrationError(
                f"ChArUco marker size {self.marker_size} m must be smaller than the square "
                f"size {self.square_size} m"
            )
        _check_ids(0, self.squares_x * self.squares_y // 2, self.dictionary)

    @cached_property
    def board(self) -> cv2.aruco.CharucoBoard:  # type: ignore[override]
        board = cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y),
            self.square_size,
            self.marker_size,
            get_dictionary(self.dictionary),
        )
        board.setLegacyPattern(self.legacy)
        return board

    @cached_property
    def chessboard_corners(self) -> Array:
        """(N, 3) inner chessboard corners (m, board frame), indexed by ChArUco corner id."""
        return np.asarray(self.board.getChessboardCorners(), np.float64).reshape(-1, 3)

    def describe(self) -> str:
        legacy = ", legacy pattern" if self.legacy else ""
        return (
            f"{self.squares_x}x{self.squares_y} ChArUco board "
            f"({short_name(self.dictionary)}{legacy})"
        )

    def spec(self) -> str:
        return (
            f"charuco:{self.squares_x}x{self.squares_y},square={self.square_size!r},"
            f"marker={self.marker_size!r}{_dict_field(self.dictionary)}"
            + (",legacy=1" if self.legacy else "")
        )

    def scaled(self, factor: float) -> Charuco:
        return Charuco(
            self.squares_x,
            self.squares_y,
            self.square_size * factor,
            self.marker_size * factor,
            self.dictionary,
            self.legacy,
        )

    def to_dict(self) -> dict[str, Any]:
        """YAML-ready mapping (see the module function ``to_dict``)."""
        return to_dict(self)

    def size_text(self) -> str:
        return f"square size {self.square_size:.3g} m (marker {self.marker_size:.3g} m)"

    def texture(self, px_per_m: float) -> TargetTexture:
        """The board with a white quiet zone of half a square, see ``TargetTexture``."""
        s = self.square_size
        # Markers sit in the white squares; every other square is black.
        with_marker = set()
        for pts in self._points.values():
            with_marker.add((int(pts[0, 0] // s), int(pts[0, 1] // s)))
        black = np.zeros((1, 1), np.uint8)
        squares: list[Square] = [
            ((i * s, j * s), black, s)
            for i in range(self.squares_x)
            for j in range(self.squares_y)
            if (i, j) not in with_marker
        ]
        squares += self._marker_squares()
        m = s / 2
        bounds = (-m, self.squares_x * s + m, -m, self.squares_y * s + m)
        return _paint(px_per_m, bounds, squares, y_down=True, viewed_from_z=-1.0)


Target = SingleTag | TagGrid | Charuco

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_FORMS = (
    "tag36h11:id=0,size=0.08",
    "tag:id=0,size=0.08,dict=DICT_4X4_50",
    "grid:4x3,marker=0.04,sep=0.01,first=0[,dict=...]",
    "charuco:5x7,square=0.04,marker=0.03[,dict=DICT_6X6_250][,legacy=1]",
)
#: Spec fields whose value is text, not a number.
_TEXT_FIELDS = {"dict"}


def _bad_spec(text: str, why: str) -> CalibrationError:
    return CalibrationError(
        f"cannot read target {text!r}: {why}; valid forms: " + ", ".join(_FORMS)
    )


def _fields(text: str, body: str, allowed: set[str], required: set[str]) -> dict[str, str]:
    fields: dict[str, str] = {}
    for part in filter(None, (p.strip() for p in body.split(","))):
        key, eq, value = part.partition("=")
        key = key.strip()
        if not eq or key not in allowed:
            raise _bad_spec(text, f"unknown field {part!r} (fields: {sorted(allowed)})")
        if key not in _TEXT_FIELDS and not re.fullmatch(_NUMBER, value.strip()):
            raise _bad_spec(text, f"{key}={value!r} is not a number")
        fields[key] = value.strip()
    missing = required - fields.keys()
    if missing:
        raise _bad_spec(text, f"missing {sorted(missing)}")
    return fields


def _int(text: str, value: str) -> int:
    number = float(value)
    if not number.is_integer():
        raise _bad_spec(text, f"{value} is not an integer")
    return int(number)


def _flag(text: str, value: str) -> bool:
    if value not in ("0", "1"):
        raise _bad_spec(text, f"legacy={value} must be 0 or 1")
    return value == "1"


def parse_target(text: str) -> Target:
    """Target from a CLI string, e.g. ``tag36h11:id=0,size=0.08``,
    ``tag:id=0,size=0.08,dict=DICT_4X4_50``, ``grid:4x3,marker=0.04,sep=0.01,first=0``,
    ``charuco:5x7,square=0.04,marker=0.03,dict=DICT_6X6_250`` (lengths in metres; ``dict=``
    takes any name of ``DICTIONARIES``, tag36h11 by default; ChArUco's ``legacy=1`` selects
    OpenCV's pattern before 4.6)."""
    kind, colon, body = text.strip().partition(":")
    kind = kind.strip().lower()
    if not colon:
        raise _bad_spec(text, "no ':' after the target kind")
    if kind in ("tag36h11", "tag"):
        f = _fields(text, body, {"id", "size", "dict"}, {"id", "size"})
        dictionary = f.get("dict", DEFAULT_DICTIONARY)
        if kind == "tag36h11" and dictionary_name(dictionary) != DEFAULT_DICTIONARY:
            raise _bad_spec(text, f"a tag36h11 target cannot take dict={dictionary}: use tag:")
        return SingleTag(_int(text, f["id"]), float(f["size"]), dictionary)
    if kind in ("grid", "charuco"):
        dims, _, rest = body.partition(",")
        match = re.fullmatch(r"\s*(\d+)\s*x\s*(\d+)\s*", dims)
        if match is None:
            raise _bad_spec(text, f"{dims!r} is not a size like 4x3")
        nx, ny = int(match[1]), int(match[2])
        if kind == "grid":
            f = _fields(text, rest, {"marker", "sep", "first", "dict"}, {"marker", "sep"})
            first = _int(text, f.get("first", "0"))
            dictionary = f.get("dict", DEFAULT_DICTIONARY)
            return TagGrid(nx, ny, float(f["marker"]), float(f["sep"]), first, dictionary)
        f = _fields(text, rest, {"square", "marker", "dict", "legacy"}, {"square", "marker"})
        return Charuco(
            nx,
            ny,
            float(f["square"]),
            float(f["marker"]),
            f.get("dict", DEFAULT_DICTIONARY),
            _flag(text, f.get("legacy", "0")),
        )
    raise _bad_spec(text, f"unknown target kind {kind!r}")


def to_dict(target: Target) -> dict[str, Any]:
    """YAML-ready mapping of a target (lengths in metres, ``dictionary`` by canonical name)."""
    if isinstance(target, SingleTag):
        out: dict[str, Any] = {"type": "tag36h11", "id": target.tag_id, "size": float(target.size)}
        if target.dictionary != DEFAULT_DICTIONARY:
            out.update(type="tag", dictionary=target.dictionary)
        return out
    if isinstance(target, TagGrid):
        return {
            "type": "grid",
            "markers_x": target.markers_x,
            "markers_y": target.markers_y,
            "marker_size": float(target.marker_size),
            "separation": float(target.separation),
            "first_id": target.first_id,
            "dictionary": target.dictionary,
        }
    return {
        "type": "charuco",
        "squares_x": target.squares_x,
        "squares_y": target.squares_y,
        "square_size": float(target.square_size),
        "marker_size": float(target.marker_size),
        "dictionary": target.dictionary,
        "legacy": target.legacy,
    }


_DICT_KEYS: dict[str, tuple[str, ...]] = {
    "tag36h11": ("id", "size"),
    "tag": ("id", "size", "dictionary"),
    "grid": ("markers_x", "markers_y", "marker_size", "separation"),
    "charuco": ("squares_x", "squares_y", "square_size", "marker_size"),
}


def target_from_dict(data: Mapping[str, Any] | str) -> Target:
    """Target from ``to_dict``'s mapping, or from a CLI string (``parse_target``)."""
    if isinstance(data, str):
        return parse_target(data)
    if not isinstance(data, Mapping):
        raise CalibrationError(f"a target must be a mapping or a string, got {data!r}")
    kind = data.get("type")
    if kind not in _DICT_KEYS:
        raise CalibrationError(
            f"target type {kind!r} is unknown; valid types: {sorted(_DICT_KEYS)}"
        )
    missing = [k for k in _DICT_KEYS[kind] if k not in data]
    if missing:
        raise CalibrationError(f"{kind} target {dict(data)} lacks {missing}")
    dictionary = data.get("dictionary", DEFAULT_DICTIONARY)
    if not isinstance(dictionary, str):
        raise CalibrationError(f"{kind} target: dictionary must be a name, got {dictionary!r}")
    try:
        if kind in ("tag36h11", "tag"):
            return SingleTag(data["id"], float(data["size"]), dictionary)
        if kind == "grid":
            return TagGrid(
                data["markers_x"],
                data["markers_y"],
                float(data["marker_size"]),
                float(data["separation"]),
                data.get("first_id", 0),
                dictionary,
            )
        legacy = data.get("legacy", False)
        if not isinstance(legacy, bool):
            raise CalibrationError(f"charuco target: legacy must be true or false, got {legacy!r}")
        return Charuco(
            data["squares_x"],
            data["squares_y"],
            float(data["square_size"]),
            float(data["marker_size"]),
            dictionary,
            legacy,
        )
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"{kind} target {dict(data)} has a bad value: {err}") from err
