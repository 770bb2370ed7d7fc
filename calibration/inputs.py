"""Calibration inputs from plain files: a folder of images and an intrinsics file.

Everything a user can get wrong raises ``CalibrationError`` naming the file, the problem and
what would be valid. Units: metres and radians.

- Images: a folder (every .png/.jpg/.jpeg/.bmp/.tif/.tiff, natural name order) or a glob.
- Intrinsics: ROS camera_info YAML (camera_calibration's ``ost.yaml``, or a CameraInfo message
  dumped as YAML), OpenCV FileStorage YAML/XML, or JSON; without a file, ``estimate_intrinsics``
  calibrates the camera from the same images.
- Flange poses: ``calibration.pose_files``.
"""

from __future__ import annotations

import glob
import logging
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from calibration.detect import Detection, scan, to_gray
from calibration.targets import Charuco, SingleTag, Target
from gaide_core.camera import Intrinsics
from gaide_core.errors import CalibrationError
from gaide_core.text_io import load_json, one_line, parse_yaml, read_text
from gaide_core.types import Array

log = logging.getLogger(__name__)

Image = npt.NDArray[np.uint8]

#: Image files a folder is searched for (case-insensitive).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
#: Distortion models accepted (ROS names; both are OpenCV's pinhole model).
DISTORTION_MODELS = ("plumb_bob", "rational_polynomial")
#: Fewest views of the target ``estimate_intrinsics`` calibrates from.
MIN_VIEWS = 3
#: From this many views on, k3 and the tangential terms are estimated too.
MANY_VIEWS = 20
#: The target's normals must spread over at least this angle (deg) across the views.
MIN_TILT_SPREAD_DEG = 10.0
#: Views whose RMS (px) exceeds ``OUTLIER_FACTOR`` times the median and ``OUTLIER_MIN_PX``
#: are dropped once and the camera is calibrated again.
OUTLIER_FACTOR, OUTLIER_MIN_PX = 5.0, 1.0
#: A camera calibration RMS (px) above this is logged as a warning.
HIGH_RMS_PX = 1.0


def natural_key(text: str) -> list[Any]:
    """Sort key ordering numbers by value: ``img2`` before ``img10``."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", text)]


# -- images ---------------------------------------------------------------------------------


def load_images(source: str | os.PathLike[str]) -> tuple[list[Path], list[Image]]:
    """The images of a folder (every ``IMAGE_SUFFIXES`` file in it) or of a glob pattern
    (``shots/*.png``), in natural name order, as (H, W, 3) RGB or (H, W) gray uint8.

    Refuses: nothing found, a file that is not a readable image, images of different sizes.
    """
    text = os.fspath(source)
    p = Path(text)
    if p.is_dir():
        paths = [
            f
            for f in p.iterdir()
            if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES and not f.name.startswith(".")
        ]
        where = f"image folder {p}"
    elif p.is_file():
        paths, where = [p], f"image {p}"
    elif any(c in text for c in "*?["):
        paths = [
            Path(m)
            for m in glob.glob(text, recursive=True)
            if Path(m).is_file() and Path(m).suffix.lower() in IMAGE_SUFFIXES
        ]
        where = f"image pattern {text!r}"
    else:
        raise CalibrationError(
            f"images {text!r} do not exist: give a folder of images or a glob pattern such as "
            "'shots/*.png'"
        )
    if not paths:
        raise CalibrationError(f"{where} holds no images (looked for {', '.join(IMAGE_SUFFIXES)})")
    paths.sort(key=lambda f: natural_key(str(f)))
    images = [_read_image(f) for f in paths]
    sizes: dict[tuple[int, int], list[Path]] = {}
    for f, im in zip(paths, images, strict=True):
        sizes.setdefault((im.shape[1], im.shape[0]), []).append(f)
    if len(sizes) > 1:
        listed = "; ".join(
            f"{w}x{h}: {len(fs)} ({fs[0].name}{', ...' if len(fs) > 1 else ''})"
            for (w, h), fs in sizes.items()
        )
        raise CalibrationError(
            f"{where}: images differ in size ({listed}); give one camera's images at one resolution"
        )
    log.info("read %d images (%dx%d) from %s", len(images), *next(iter(sizes)), where)
    return paths, images


def _read_image(path: Path) -> Image:
    try:
        data = path.read_bytes()
    except OSError as err:
        raise CalibrationError(f"image {path} cannot be read: {err.strerror or err}") from err
    image = None
    if data:
        try:
            image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_ANYCOLOR)
        except cv2.error:
            image = None
    if image is None:
        raise CalibrationError(
            f"image {path} is empty, corrupt or not an image (readable: PNG, JPEG, BMP, TIFF)"
        )
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    return np.ascontiguousarray(image, np.uint8)


# -- intrinsics -----------------------------------------------------------------------------

_WIDTH_KEYS = ("image_width", "width")
_HEIGHT_KEYS = ("image_height", "height")
_K_KEYS = ("camera_matrix", "K", "k", "cameraMatrix")
_D_KEYS = ("distortion_coefficients", "D", "d", "dist_coeffs", "distCoeffs")
_FORMATS = (
    "ROS camera_info YAML (image_width, image_height, camera_matrix, distortion_model, "
    "distortion_coefficients), a CameraInfo message as YAML (width, height, k, d), OpenCV "
    "FileStorage YAML/XML (camera_matrix, distortion_coefficients, image_width, image_height) "
    "or JSON (K or fx, fy, cx, cy; D; width; height)"
)


def load_intrinsics(
    path: str | os.PathLike[str], image_shape: Sequence[int] | None = None
) -> Intrinsics:
    """Pinhole intrinsics (``K`` px, OpenCV ``D``) from a file in any of these formats:

    - ROS camera_info YAML as ``camera_calibration`` writes it, or a ``CameraInfo`` message
      dumped as YAML (``width``, ``height``, ``k``, ``d``, ``distortion_model``);
    - OpenCV FileStorage YAML (``%YAML:1.0``) or XML: ``camera_matrix``/``cameraMatrix``/``K``,
      ``distortion_coefficients``/``distCoeffs``/``dist_coeffs``/``D``, the image size;
    - JSON with ``K`` (3x3 or 9 numbers) or ``fx, fy, cx, cy``, ``D``, ``width``, ``height``.

    Only the ``plumb_bob`` and ``rational_polynomial`` models (OpenCV's pinhole model).
    ``image_shape``: the images' numpy shape (H, W[, C]); it fills in a size the file lacks
    (or gives as 0x0) and must match a size it gives.
    """
    p = Path(path)
    where = f"intrinsics file {p}"
    suffix = p.suffix.lower()
    if suffix == ".json":
        data = load_json(p, "intrinsics file", CalibrationError)
    else:
        text = read_text(p, "intrinsics file", CalibrationError)
        opencv = text.lstrip().startswith(("%YAML:", "<?xml", "<opencv_storage"))
        if suffix == ".xml" or opencv or "!!opencv-matrix" in text:
            data = _read_filestorage(p, where)
        else:
            # `ros2 topic echo --once` ends the message with a document separator.
            text = re.sub(r"\n---\s*$", "\n", text)
            data = parse_yaml(text, where, CalibrationError)
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{where} must be a mapping; valid formats: {_FORMATS}")
    intrinsics = _intrinsics_from(data, where, image_shape)
    log.info(
        "intrinsics from %s: %dx%d, fx %.1f px",
        p,
        intrinsics.width,
        intrinsics.height,
        intrinsics.fx,
    )
    return intrinsics


def check_image_size(
    intrinsics: Intrinsics, image_shape: Sequence[int], where: str = "the intrinsics"
) -> None:
    """Refuse intrinsics for another image size than ``image_shape`` (H, W[, C])."""
    height, width = int(image_shape[0]), int(image_shape[1])
    w, h = intrinsics.width, intrinsics.height
    if (w, h) == (width, height):
        return
    hint = ""
    if w * height == h * width:
        hint = f" (scaled by {width / w:g}: scale K by it too, or calibrate at this size)"
    raise CalibrationError(
        f"{where} are for {w}x{h} images but the images are {width}x{height}{hint}; give the "
        "intrinsics of this camera at this resolution"
    )


def _read_filestorage(path: Path, where: str) -> dict[str, Any]:
    """An OpenCV FileStorage file as a mapping (matrices as arrays)."""
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as err:  # OpenCV's parse errors come as SystemError
        cause = err.__cause__ or err
        detail = one_line(cause).split("error: ", 1)[-1]
        raise CalibrationError(f"{where} is not a valid OpenCV FileStorage file: {detail}") from err
    try:
        if not fs.isOpened():
            raise CalibrationError(f"{where} cannot be opened as an OpenCV FileStorage file")
        return {key: _node_value(fs.getNode(key)) for key in fs.root().keys()}  # noqa: SIM118
    finally:
        fs.release()


def _node_value(node: Any) -> Any:
    if node.isMap():
        keys = node.keys()
        if "dt" in keys and "data" in keys:  # an !!opencv-matrix
            return np.asarray(node.mat(), np.float64)
        return {key: _node_value(node.getNode(key)) for key in keys}
    if node.isSeq():
        return [_node_value(node.at(i)) for i in range(node.size())]
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return float(node.real())
    if node.isString():
        return node.string()
    return None


def _intrinsics_from(
    data: Mapping[str, Any], where: str, image_shape: Sequence[int] | None
) -> Intrinsics:
    model = _distortion_model(data, where)
    K = _camera_matrix(data, where)
    D_key = _first_key(data, _D_KEYS)
    D = np.zeros(0) if D_key is None else numbers(data[D_key], f"{where}: {D_key}").ravel()
    if model is None:
        model = "plumb_bob" if D.size <= 5 else "rational_polynomial"
    width, height = (_integer(data, keys, where) for keys in (_WIDTH_KEYS, _HEIGHT_KEYS))
    if not width and not height and image_shape is not None:
        width, height = int(image_shape[1]), int(image_shape[0])
    if width is None or height is None:
        raise CalibrationError(
            f"{where} gives no image size: add image_width and image_height (or width and "
            "height) in pixels"
        )
    intrinsics = Intrinsics.checked(width, height, K, D, model, error=CalibrationError, where=where)
    if not (0 <= intrinsics.cx <= width and 0 <= intrinsics.cy <= height):
        raise CalibrationError(
            f"{where}: the principal point ({intrinsics.cx:g}, {intrinsics.cy:g}) px lies "
            f"outside the {width}x{height} image; check K and the image size"
        )
    if image_shape is not None:
        check_image_size(intrinsics, image_shape, f"the intrinsics in {where}")
    return intrinsics


def _first_key(data: Mapping[str, Any], keys: Sequence[str]) -> str | None:
    return next((k for k in keys if k in data and data[k] is not None), None)


def _distortion_model(data: Mapping[str, Any], where: str) -> str | None:
    if data.get("fisheye_model"):  # OpenCV's calibration sample marks fisheye files so
        raise _fisheye(where, "fisheye_model")
    model = data.get("distortion_model")
    if model is None or model == "":
        return None
    name = str(model).strip().lower()
    if name in ("equidistant", "fisheye", "kannala_brandt"):
        raise _fisheye(where, name)
    if name not in DISTORTION_MODELS:
        raise CalibrationError(
            f"{where}: distortion_model {model!r} is not supported; valid: "
            f"{', '.join(DISTORTION_MODELS)}"
        )
    return name


def _fisheye(where: str, name: str) -> CalibrationError:
    return CalibrationError(
        f"{where} uses a fisheye model ({name}), which is not supported: target detection and "
        f"PnP use OpenCV's pinhole model ({', '.join(DISTORTION_MODELS)}); calibrate the camera "
        "with a pinhole model, or give no intrinsics file to estimate them from the images"
    )


def _camera_matrix(data: Mapping[str, Any], where: str) -> Array:
    key = _first_key(data, _K_KEYS)
    if key is not None:
        values = numbers(data[key], f"{where}: {key}")
        if values.size != 9:
            raise CalibrationError(
                f"{where}: {key} must be a 3x3 matrix or 9 numbers, got shape {values.shape}"
            )
        K = values.reshape(3, 3)
        if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0:
            raise CalibrationError(
                f"{where}: {key} must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], got "
                f"{K.tolist()} (is it transposed?)"
            )
        return K
    if all(k in data for k in ("fx", "fy", "cx", "cy")):
        fx, fy, cx, cy = (numbers(data[k], f"{where}: {k}") for k in ("fx", "fy", "cx", "cy"))
        if any(v.size != 1 for v in (fx, fy, cx, cy)):
            raise CalibrationError(f"{where}: fx, fy, cx and cy must be single numbers")
        return np.array([[fx.item(), 0.0, cx.item()], [0.0, fy.item(), cy.item()], [0, 0, 1.0]])
    raise CalibrationError(
        f"{where} has no camera matrix: expected one of {', '.join(_K_KEYS)} or fx, fy, cx, cy "
        f"(keys found: {sorted(map(str, data))}); valid formats: {_FORMATS}"
    )


def numbers(value: Any, where: str) -> Array:
    """An array from a list, nested lists, an OpenCV matrix or ROS's ``{rows, cols, data}``."""
    if isinstance(value, Mapping):
        if "data" not in value:
            raise CalibrationError(f"{where} must hold numbers or {{rows, cols, data}}")
        data = numbers(value["data"], where)
        rows, cols = value.get("rows"), value.get("cols")
        if isinstance(rows, int) and isinstance(cols, int):
            if data.size != rows * cols:
                raise CalibrationError(
                    f"{where}: rows {rows} x cols {cols} but data holds {data.size} numbers"
                )
            return data.reshape(rows, cols)
        return data
    try:
        array = np.asarray(value, np.float64)
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"{where} must hold numbers, got {value!r}") from err
    if not np.all(np.isfinite(array)):
        raise CalibrationError(f"{where} holds a value that is not finite: {array.tolist()}")
    return array


def _integer(data: Mapping[str, Any], keys: Sequence[str], where: str) -> int | None:
    key = _first_key(data, keys)
    if key is None:
        return None
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
        raise CalibrationError(f"{where}: {key} must be a whole number of pixels, got {value!r}")
    return int(value)


# -- intrinsics from the images -------------------------------------------------------------


def estimate_intrinsics(images: Sequence[Image], target: Target) -> tuple[Intrinsics, float]:
    """Calibrate the camera from images of a ChArUco board or a tag grid
    (``cv2.calibrateCamera``): returns the intrinsics and the reprojection RMS (px).

    Needs the target in at least ``MIN_VIEWS`` images, tilted differently (its normal spread
    over ``MIN_TILT_SPREAD_DEG``). Model: plumb_bob with k1, k2 (k3 and the tangential terms
    fixed at 0 below ``MANY_VIEWS`` views). A single tag (4 points a view) is refused.
    """
    if isinstance(target, SingleTag):
        raise CalibrationError(
            f"a single tag ({target.describe()}) gives 4 points per image, too few to "
            "estimate the camera's intrinsics: use a ChArUco board or a tag grid, or give "
            "the intrinsics file"
        )
    if len(images) == 0:
        raise CalibrationError("no images given: estimating intrinsics needs at least 3")
    shapes = {np.shape(im)[:2] for im in images}
    if len(shapes) != 1:
        raise CalibrationError(f"images differ in size {sorted(shapes)}: give one camera's images")
    height, width = shapes.pop()
    grays = [to_gray(im) for im in images]
    # Detection needs a K only to interpolate ChArUco corners: a guess will do at first.
    K = np.array([[width, 0.0, (width - 1) / 2], [0.0, width, (height - 1) / 2], [0, 0, 1.0]])
    detections = _views(grays, target, K, None)
    rms, K, D, views = _calibrate(detections, (width, height))
    if isinstance(target, Charuco):  # interpolate the corners again with the estimate
        rms, K, D, views = _calibrate(_views(grays, target, K, D), (width, height))
    intrinsics = Intrinsics.checked(
        width,
        height,
        K,
        D.ravel(),
        "plumb_bob",
        error=CalibrationError,
        where="estimated intrinsics",
    )
    log.info(
        "estimated intrinsics from %d views: fx %.1f fy %.1f cx %.1f cy %.1f px, RMS %.3f px",
        views,
        intrinsics.fx,
        intrinsics.fy,
        intrinsics.cx,
        intrinsics.cy,
        rms,
    )
    return intrinsics, rms


def _views(grays: Sequence[Image], target: Target, K: Array, D: Array | None) -> list[Detection]:
    found = [d for d in (scan(g, target, K, D) for g in grays) if d.found]
    if len(found) < MIN_VIEWS:
        raise CalibrationError(
            f"{target.describe()} found in {len(found)} of {len(grays)} images: estimating "
            f"intrinsics needs it in at least {MIN_VIEWS}, tilted differently (or give the "
            "intrinsics file)"
        )
    return found


def _calibrate(
    views: Sequence[Detection], size: tuple[int, int]
) -> tuple[float, Array, Array, int]:
    """RMS (px), K, D and the number of views used, after dropping outlier views once."""
    flags = 0 if len(views) >= MANY_VIEWS else cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3
    obj = [d.object_points.astype(np.float32) for d in views]
    img = [d.image_points.astype(np.float32).reshape(-1, 1, 2) for d in views]
    try:
        rms, K, D, rvecs, _, _, _, per_view = cv2.calibrateCameraExtended(
            obj, img, size, np.eye(3), np.zeros(5), flags=flags
        )
        errors = np.ravel(per_view)
        keep = errors <= max(OUTLIER_MIN_PX, OUTLIER_FACTOR * float(np.median(errors)))
        if not keep.all() and keep.sum() >= MIN_VIEWS:
            log.info("dropping %d views with RMS %s px", (~keep).sum(), errors[~keep].round(2))
            obj = [o for o, k in zip(obj, keep, strict=True) if k]
            img = [i for i, k in zip(img, keep, strict=True) if k]
            rms, K, D, rvecs, _ = cv2.calibrateCamera(
                obj, img, size, np.eye(3), np.zeros(5), flags=flags
            )
    except cv2.error as err:
        raise CalibrationError(
            f"OpenCV could not calibrate the camera from {len(views)} views: {one_line(err)}"
        ) from err
    normals = np.array([cv2.Rodrigues(r)[0][:, 2] for r in rvecs])
    spread = np.degrees(np.arccos(np.clip(normals @ normals.T, -1.0, 1.0)).max())
    if spread < MIN_TILT_SPREAD_DEG:
        raise CalibrationError(
            f"the target's views differ in tilt by only {spread:.1f} deg, so the focal length "
            f"cannot be told from the distance: tilt the target by 20-40 deg in different "
            f"directions (at least {MIN_TILT_SPREAD_DEG:g} deg apart), or give the intrinsics "
            "file"
        )
    if rms > HIGH_RMS_PX:
        log.warning("camera calibration RMS %.2f px is high: check the target spec", rms)
    return float(rms), np.asarray(K, np.float64), np.asarray(D, np.float64), len(obj)
