"""Calibration inputs from plain files: images, intrinsics (read or estimated), flange poses."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from calibration import inputs
from calibration.detect import Detection
from calibration.inputs import (
    MANY_VIEWS,
    check_image_size,
    estimate_intrinsics,
    load_images,
    load_intrinsics,
    natural_key,
)
from calibration.pose_files import FlangePoses, load_poses, order_by_images
from calibration.targets import Charuco, SingleTag, TagGrid
from gaide_core.camera import Intrinsics
from gaide_core.errors import CalibrationError
from gaide_core.transforms import from_xyz_quat, from_xyz_rpy, make_transform
from tests.calibration.synth import HEIGHT, WIDTH, K, look_at_target, render

# -- images ---------------------------------------------------------------------------------


def _write_image(
    path: Path, size: tuple[int, int] = (32, 24), bgr: tuple[int, ...] = (255, 0, 0)
) -> None:
    w, h = size
    image = np.zeros((h, w, 3), np.uint8)
    image[:] = bgr
    assert cv2.imwrite(str(path), image)


def test_natural_order() -> None:
    names = ["img10.png", "img2.png", "IMG1.png", "img2b.png"]
    assert sorted(names, key=natural_key) == ["IMG1.png", "img2.png", "img2b.png", "img10.png"]


def test_load_images_from_a_folder(tmp_path: Path) -> None:
    for name in ("img10.png", "img2.png", "img1.jpg", "img3.TIFF"):
        _write_image(tmp_path / name)
    (tmp_path / "notes.txt").write_text("not an image")
    _write_image(tmp_path / ".hidden.png")
    (tmp_path / "sub.png").mkdir()
    paths, images = load_images(tmp_path)
    assert [p.name for p in paths] == ["img1.jpg", "img2.png", "img3.TIFF", "img10.png"]
    assert all(im.shape == (24, 32, 3) and im.dtype == np.uint8 for im in images)
    # Written as BGR (255, 0, 0), blue: read back as RGB.
    assert images[1][0, 0].tolist() == [0, 0, 255]


def test_load_images_from_a_glob_keeps_gray(tmp_path: Path) -> None:
    for i in (1, 2, 11):
        assert cv2.imwrite(str(tmp_path / f"shot_{i}.png"), np.full((10, 12), 7 * i, np.uint8))
    _write_image(tmp_path / "other_1.png")
    paths, images = load_images(str(tmp_path / "shot_*.png"))
    assert [p.name for p in paths] == ["shot_1.png", "shot_2.png", "shot_11.png"]
    assert images[2].shape == (10, 12) and int(images[2][0, 0]) == 77


def test_load_images_errors(tmp_path: Path) -> None:
    with pytest.raises(
        CalibrationError, match=r"image folder .* holds no images \(looked for \.png"
    ):
        load_images(tmp_path)
    with pytest.raises(CalibrationError, match=r"image pattern .* holds no images"):
        load_images(str(tmp_path / "*.jpg"))
    with pytest.raises(CalibrationError, match="do not exist: give a folder of images or a glob"):
        load_images(tmp_path / "missing")
    _write_image(tmp_path / "a1.png")
    (tmp_path / "a2.png").write_bytes(b"\x89PNG\r\n\x1a\ntruncated")
    with pytest.raises(
        CalibrationError, match=r"image .*a2\.png is empty, corrupt or not an image"
    ):
        load_images(tmp_path)
    (tmp_path / "a2.png").write_bytes(b"")
    with pytest.raises(CalibrationError, match=r"a2\.png is empty"):
        load_images(tmp_path)
    _write_image(tmp_path / "a2.png", size=(64, 48))
    _write_image(tmp_path / "a3.png", size=(64, 48))
    with pytest.raises(
        CalibrationError,
        match=r"images differ in size \(32x24: 1 \(a1\.png\); 64x48: 2 \(a2\.png, \.\.\.\)\)",
    ):
        load_images(tmp_path)


# -- intrinsics -----------------------------------------------------------------------------

K_FILE = [[615.2, 0.0, 320.5], [0.0, 614.8, 239.1], [0.0, 0.0, 1.0]]
D_FILE = [0.11, -0.23, 0.001, -0.002, 0.05]


def _check(intr: Intrinsics, model: str = "plumb_bob", D: list[float] = D_FILE) -> None:
    assert (intr.width, intr.height) == (640, 480)
    np.testing.assert_allclose(intr.K, K_FILE)
    np.testing.assert_allclose(intr.D, D)
    assert intr.distortion_model == model


def test_ros_camera_info_yaml(tmp_path: Path) -> None:
    # As camera_calibration / camera_info_manager write it (ost.yaml).
    flat = [v for row in K_FILE for v in row]
    path = tmp_path / "ost.yaml"
    path.write_text(
        f"""image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: {flat}
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: {D_FILE}
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [615.2, 0, 320.5, 0, 0, 614.8, 239.1, 0, 0, 0, 1, 0]
"""
    )
    _check(load_intrinsics(path, (480, 640, 3)))


def test_ros2_camera_info_message_yaml(tmp_path: Path) -> None:
    # `ros2 topic echo --once /camera/color/camera_info > info.yaml`
    D8 = [*D_FILE, 0.01, 0.002, 0.003]
    path = tmp_path / "info.yaml"
    path.write_text(
        "header:\n  stamp:\n    sec: 1\n    nanosec: 2\n  frame_id: camera_color_optical_frame\n"
        f"height: 480\nwidth: 640\ndistortion_model: rational_polynomial\nd: {D8}\n"
        f"k: {[v for row in K_FILE for v in row]}\nr: [1.0, 0, 0, 0, 1, 0, 0, 0, 1]\n"
        "p: [615.2, 0, 320.5, 0, 0, 614.8, 239.1, 0, 0, 0, 1, 0]\nbinning_x: 0\nbinning_y: 0\n"
        "roi:\n  x_offset: 0\n  y_offset: 0\n  height: 0\n  width: 0\n  do_rectify: false\n---\n"
    )
    _check(load_intrinsics(path), "rational_polynomial", D8)


def test_opencv_filestorage_yaml_and_xml(tmp_path: Path) -> None:
    yaml_path = tmp_path / "calib.yaml"
    fs = cv2.FileStorage(str(yaml_path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", np.array(K_FILE))
    fs.write("distortion_coefficients", np.array([D_FILE]))
    fs.write("fisheye_model", 0)
    fs.release()
    assert yaml_path.read_text().startswith("%YAML:1.0")
    _check(load_intrinsics(yaml_path))
    xml_path = tmp_path / "calib.xml"
    fs = cv2.FileStorage(str(xml_path), cv2.FILE_STORAGE_WRITE)
    fs.write("cameraMatrix", np.array(K_FILE))
    fs.write("distCoeffs", np.array(D_FILE).reshape(5, 1))
    fs.write("width", 640)
    fs.write("height", 480)
    fs.release()
    _check(load_intrinsics(xml_path))


def test_json_intrinsics(tmp_path: Path) -> None:
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"K": K_FILE, "D": D_FILE, "width": 640, "height": 480}))
    _check(load_intrinsics(path))
    flat = {"K": [v for row in K_FILE for v in row], "D": D_FILE, "width": 640, "height": 480}
    path.write_text(json.dumps(flat))
    _check(load_intrinsics(path))
    # fx, fy, cx, cy without a size or distortion: the size comes from the images.
    path.write_text(json.dumps({"fx": 615.2, "fy": 614.8, "cx": 320.5, "cy": 239.1}))
    intr = load_intrinsics(path, (480, 640))
    _check(intr, D=[])
    assert intr.fx == 615.2


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            "distortion_model: equidistant",
            r"uses a fisheye model \(equidistant\), which is not supported",
        ),
        ("distortion_model: fisheye", "fisheye model"),
        (
            "distortion_model: double_sphere",
            r"'double_sphere' is not supported; valid: plumb_bob, rational_polynomial",
        ),
        (
            "K: [[615, 0, 0], [0, 615, 0], [320, 240, 1]]",
            r"K must be \[\[fx, 0, cx\].* \(is it transposed\?\)",
        ),
        ("K: [615, 0, 320, 0, 615, 240]", r"K must be a 3x3 matrix or 9 numbers, got shape \(6,\)"),
        ("K: [[-615, 0, 320], [0, 615, 240], [0, 0, 1]]", "positive focal lengths"),
        (
            "K: [[615, 0, 900], [0, 615, 240], [0, 0, 1]]",
            r"principal point \(900, 240\) px lies outside the 640x480",
        ),
        (
            "K: [[615, 0, 320], [0, 615, 240], [0, 0, 1]]\nD: [1, 2, 3]",
            "4, 5, 8, 12 or 14 finite OpenCV coefficients",
        ),
        (
            "camera: {}",
            r"has no camera matrix: expected one of camera_matrix, K, .*\(keys found: \['camera', 'height', 'width'\]\)",
        ),
        (
            "camera_matrix: {rows: 3, cols: 3, data: [1, 2]}",
            "rows 3 x cols 3 but data holds 2 numbers",
        ),
        ("K: [[615, 0, 320], [0, 615, 240], [0, 0, one]]", "must hold numbers"),
    ],
)
def test_intrinsics_errors(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.yaml"
    if not text.startswith(("K", "camera")):
        text += "\nK: [[615, 0, 320], [0, 615, 240], [0, 0, 1]]"
    path.write_text(text + "\nwidth: 640\nheight: 480\n")
    with pytest.raises(CalibrationError, match=rf"intrinsics file .*bad\.yaml.*{match}"):
        load_intrinsics(path)


def test_intrinsics_file_errors(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match=r"intrinsics file .*none\.yaml does not exist"):
        load_intrinsics(tmp_path / "none.yaml")
    path = tmp_path / "cam.yaml"
    path.write_text("K: [[615, 0, 320], [0, 615, 240], [0, 0, 1]\n")
    with pytest.raises(CalibrationError, match=r"cam\.yaml is not valid YAML: line"):
        load_intrinsics(path)
    path.write_text("- 1\n- 2\n")
    with pytest.raises(CalibrationError, match=r"cam\.yaml must be a mapping; valid formats: ROS"):
        load_intrinsics(path)
    path.write_text("%YAML:1.0\n---\ncamera_matrix: [1, 2\n")
    with pytest.raises(
        CalibrationError, match=r"cam\.yaml is not a valid OpenCV FileStorage file: .*Missing ,"
    ):
        load_intrinsics(path)
    path.write_text(
        "%YAML:1.0\n---\nfisheye_model: 1\ncamera_matrix: [615, 0, 320, 0, 615, 240, 0, 0, 1]\n"
    )
    with pytest.raises(CalibrationError, match=r"fisheye model \(fisheye_model\)"):
        load_intrinsics(path)
    path.write_text("K: [615, 0, 320, 0, 615, 240, 0, 0, 1]\n")
    with pytest.raises(
        CalibrationError, match=r"cam\.yaml gives no image size: add image_width and image_height"
    ):
        load_intrinsics(path)
    path.write_text("K: [615, 0, 320, 0, 615, 240, 0, 0, 1]\nwidth: 640.5\nheight: 480\n")
    with pytest.raises(
        CalibrationError, match=r"width must be a whole number of pixels, got 640.5"
    ):
        load_intrinsics(path)
    json_path = tmp_path / "cam.json"
    json_path.write_text('{"K": [1, 2,]}')
    with pytest.raises(CalibrationError, match=r"cam\.json is not valid JSON: line 1"):
        load_intrinsics(json_path)


def test_intrinsics_for_another_image_size(tmp_path: Path) -> None:
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"K": K_FILE, "D": D_FILE, "width": 640, "height": 480}))
    with pytest.raises(
        CalibrationError,
        match=r"cam\.json are for 640x480 images but the images are 1280x960 \(scaled by 2: "
        "scale K by it too.*; give the intrinsics of this camera at this resolution",
    ):
        load_intrinsics(path, (960, 1280, 3))
    intr = load_intrinsics(path)
    check_image_size(intr, (480, 640))
    with pytest.raises(
        CalibrationError, match=r"are for 640x480 images but the images are 848x480; give"
    ):
        check_image_size(intr, (480, 848, 3))


# -- intrinsics from the images -------------------------------------------------------------

BOARD = Charuco(7, 5, 0.04, 0.03, "DICT_6X6_250")
# Views of the board's centre 0.5 m away, tilted up to 0.55 rad in different directions.
TILTS = [
    (0.0, 0.0, 0.0),
    (0.45, 0.0, 0.1),
    (-0.45, 0.05, -0.1),
    (0.0, 0.5, 0.2),
    (0.05, -0.5, -0.2),
    (0.35, 0.35, 0.0),
    (-0.35, 0.35, 0.3),
    (0.35, -0.4, -0.3),
    (-0.3, -0.3, 0.15),
    (0.2, 0.55, -0.1),
]


def _board_view(
    board: Charuco | TagGrid, rpy: tuple[float, float, float], offset: float
) -> np.ndarray:
    """``T_cam_board`` with the board's centre at (offset, offset / 2, 0.5) m, turned by rpy."""
    tex = board.texture(100.0)  # its extent is centred on the board
    x0, x1, y0, y1 = tex.extent
    centre = make_transform(None, np.array([-(x0 + x1) / 2, -(y0 + y1) / 2, 0.0]))
    return look_at_target([offset, offset / 2, 0.5], rpy, -1.0) @ centre


def test_estimate_intrinsics_from_charuco_views(rng: np.random.Generator) -> None:
    images = [
        render(BOARD, _board_view(BOARD, rpy, 0.02 * (i % 3 - 1)), rng)
        for i, rpy in enumerate(TILTS)
    ]
    intr, rms = estimate_intrinsics(images, BOARD)
    assert (intr.width, intr.height) == (WIDTH, HEIGHT)
    assert abs(intr.fx / K[0, 0] - 1) < 0.01 and abs(intr.fy / K[1, 1] - 1) < 0.01, intr.K
    assert abs(intr.cx - K[0, 2]) < 3 and abs(intr.cy - K[1, 2]) < 3, intr.K
    assert np.all(np.abs(intr.D[2:]) == 0)  # few views: k3 and tangential fixed
    assert 0 < rms < 0.5


def test_estimate_intrinsics_from_a_tag_grid(rng: np.random.Generator) -> None:
    grid = TagGrid(4, 3, 0.05, 0.012)
    images = [render(grid, _board_view(grid, rpy, 0.0), rng) for rpy in TILTS[1:7]]
    intr, rms = estimate_intrinsics(images, grid)
    assert abs(intr.fx / K[0, 0] - 1) < 0.01, intr.K
    assert rms < 0.5


def test_estimate_intrinsics_with_many_views_drops_a_bad_one(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From ``MANY_VIEWS`` views on the tangential terms are estimated; a view whose points
    are off (a bad detection) is left out. Detections are projected, not rendered."""
    grid = TagGrid(4, 3, 0.05, 0.012)
    obj = np.concatenate([grid.marker_corners(i) for i in grid.ids])
    D_true = np.array([-0.12, 0.06, 0.002, -0.001, 0.0])
    detections = []
    for i in range(MANY_VIEWS + 2):
        rpy = (rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3))
        T = _board_view(grid, rpy, rng.uniform(-0.05, 0.05))
        img, _ = cv2.projectPoints(obj, cv2.Rodrigues(T[:3, :3])[0], T[:3, 3], K, D_true)
        img = img.reshape(-1, 2) + rng.normal(0, 0.05, (len(obj), 2))
        if i == 5:
            img += rng.normal(0, 6.0, img.shape)
        ids = np.repeat(np.array(grid.ids), 4)
        detections.append(Detection(obj, img, ids, grid.ids, (), np.zeros((0, 4, 2))))
    images = [np.full((HEIGHT, WIDTH), i, np.uint8) for i in range(len(detections))]

    def fake_scan(image: np.ndarray, *_: object) -> Detection:
        return detections[int(image[0, 0])]

    monkeypatch.setattr(inputs, "scan", fake_scan)
    intr, rms = estimate_intrinsics(images, grid)
    np.testing.assert_allclose(intr.K, K, rtol=2e-3, atol=0.5)
    np.testing.assert_allclose(intr.D[2:4], D_true[2:4], atol=3e-4)
    assert rms < 0.1  # the bad view (6 px noise) was left out


def test_estimate_intrinsics_refusals(rng: np.random.Generator) -> None:
    tag = SingleTag(0, 0.1)
    with pytest.raises(
        CalibrationError, match=r"a single tag \(tag36h11 tag id 0 \(0.1 m\)\) gives 4 points"
    ):
        estimate_intrinsics([np.zeros((48, 64), np.uint8)] * 5, tag)
    with pytest.raises(CalibrationError, match="no images given"):
        estimate_intrinsics([], BOARD)
    blank = rng.integers(0, 255, (HEIGHT, WIDTH, 3), dtype=np.uint8)
    two = [render(BOARD, _board_view(BOARD, rpy, 0.0), rng) for rpy in TILTS[1:3]]
    with pytest.raises(
        CalibrationError,
        match=r"7x5 ChArUco board \(DICT_6X6_250\) found in 2 of 3 images: .* at least 3",
    ):
        estimate_intrinsics([*two, blank], BOARD)
    flat = [
        render(BOARD, _board_view(BOARD, (0.0, 0.0, 0.0), off), rng) for off in (-0.04, 0.0, 0.04)
    ]
    with pytest.raises(CalibrationError, match=r"views differ in tilt by only \d+\.\d deg"):
        estimate_intrinsics(flat, BOARD)


# -- flange poses ---------------------------------------------------------------------------


def _T(poses: FlangePoses) -> np.ndarray:
    assert poses.T_base_flange is not None and poses.joints is None
    return poses.T_base_flange


def _q(poses: FlangePoses) -> np.ndarray:
    assert poses.joints is not None and poses.T_base_flange is None
    return poses.joints


QUATS = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.7071068, 0.0, 0.7071068], [0.5, 0.5, -0.5, 0.5]]
XYZS = [[0.4, 0.0, 0.5], [0.3, -0.2, 0.6], [0.5, 0.1, 0.35]]
EXPECTED = np.array(
    [from_xyz_quat(x, np.array(q) / np.linalg.norm(q)) for x, q in zip(XYZS, QUATS, strict=True)]
)


def test_yaml_pose_list_with_images(tmp_path: Path) -> None:
    path = tmp_path / "poses.yaml"
    path.write_text(
        "".join(
            f"- {{image: img{i}.png, xyz: {x}, quat_xyzw: {q}}}\n"
            for i, (x, q) in enumerate(zip(XYZS, QUATS, strict=True))
        )
    )
    poses = load_poses(path, count=3)
    assert poses.joints is None and poses.T_base_flange is not None
    np.testing.assert_allclose(_T(poses), EXPECTED, atol=1e-6)
    assert poses.names == ("img0.png", "img1.png", "img2.png")
    assert len(poses) == 3


def test_yaml_mapping_of_matrices_and_json(tmp_path: Path) -> None:
    path = tmp_path / "poses.yaml"
    path.write_text("poses:\n" + "".join(f"  - matrix: {T.tolist()}\n" for T in EXPECTED))
    poses = load_poses(path)
    np.testing.assert_allclose(_T(poses), EXPECTED)
    assert poses.names is None
    json_path = tmp_path / "poses.json"
    json_path.write_text(
        json.dumps([{"xyz": x, "quat_xyzw": q} for x, q in zip(XYZS, QUATS, strict=True)])
    )
    np.testing.assert_allclose(_T(load_poses(json_path)), EXPECTED, atol=1e-6)


def test_yaml_joints(tmp_path: Path) -> None:
    path = tmp_path / "joints.yaml"
    path.write_text(
        "joint_names: [a1, a2, a3]\nposes:\n"
        "  - {joints: [0.1, -0.2, 0.3], image: shot1}\n  - {joints: [0.0, 1.0, -1.5], image: shot2}\n"
    )
    poses = load_poses(path, 2)
    assert poses.T_base_flange is None
    np.testing.assert_allclose(_q(poses), [[0.1, -0.2, 0.3], [0.0, 1.0, -1.5]])
    assert poses.joint_names == ("a1", "a2", "a3") and poses.names == ("shot1", "shot2")


def test_csv_poses(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    rows = [
        f"{name},{','.join(map(str, x))},{','.join(map(str, q))},{1000 + i}"
        for i, (name, x, q) in enumerate(zip("abc", XYZS, QUATS, strict=True))
    ]
    path.write_text(
        "# recorded poses\nimage, x, y, z, qx, qy, qz, qw, stamp\n" + "\n".join(rows) + "\n\n"
    )
    poses = load_poses(path, 3)
    np.testing.assert_allclose(_T(poses), EXPECTED, atol=1e-6)
    assert poses.names == ("a", "b", "c")


def test_csv_joints_numbered_and_named(tmp_path: Path) -> None:
    path = tmp_path / "joints.csv"
    # Columns out of order: read in joint-number order; tab-separated.
    path.write_text("j2\tj1\tj3\n0.2\t0.1\t0.3\n-0.2\t-0.1\t-0.3\n")
    poses = load_poses(path, 2)
    np.testing.assert_allclose(_q(poses), [[0.1, 0.2, 0.3], [-0.1, -0.2, -0.3]])
    assert poses.joint_names is None and poses.names is None
    path.write_text("joint_0;joint_1\n0.5;0.6\n")
    np.testing.assert_allclose(_q(load_poses(path)), [[0.5, 0.6]])
    path.write_text("image,shoulder_pan_joint,elbow_joint\nimg1.png,0.1,0.2\nimg2.png,0.3,0.4\n")
    poses = load_poses(path)
    assert poses.joint_names == ("shoulder_pan_joint", "elbow_joint")
    assert poses.names == ("img1.png", "img2.png")


def test_pose_folder(tmp_path: Path) -> None:
    T0, T1, T2 = EXPECTED
    (tmp_path / "img10.txt").write_text("\n".join(" ".join(f"{v:.4f}" for v in row) for row in T2))
    (tmp_path / "img2.txt").write_text(" ".join(map(str, [*XYZS[1], *QUATS[1]])))
    (tmp_path / "img1.json").write_text(json.dumps({"matrix": T0.tolist()}))
    _write_image(tmp_path / "img1.png")  # images beside the poses are not poses
    poses = load_poses(tmp_path, 3)
    assert poses.names == ("img1", "img2", "img10")
    # The 4-decimal matrix is made rigid again (within 1e-4 of the original).
    np.testing.assert_allclose(_T(poses), [T0, T1, T2], atol=2e-4)
    assert poses.T_base_flange is not None
    R = poses.T_base_flange[2, :3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    (tmp_path / "img2.txt").unlink()
    (tmp_path / "img2.yaml").write_text("joints: [0.1, 0.2]\n")
    with pytest.raises(
        CalibrationError, match=r"mixes joint vectors \(pose file .*img2\.yaml\) and poses"
    ):
        load_poses(tmp_path)


def test_unit_checks(tmp_path: Path) -> None:
    path = tmp_path / "poses.yaml"
    # Within 1e-3 of unit length: normalised.
    path.write_text("- {xyz: [0.1, 0, 0.5], quat_xyzw: [0, 0, 0, 1.0009]}\n")
    np.testing.assert_allclose(_T(load_poses(path))[0], from_xyz_quat([0.1, 0, 0.5], [0, 0, 0, 1]))
    path.write_text("- {xyz: [0.1, 0, 0.5], quat_xyzw: [0, 0, 0, 1.01]}\n")
    with pytest.raises(
        CalibrationError, match=r"entry 1: xyz must be 3 numbers and quat_xyzw a unit quaternion"
    ):
        load_poses(path)
    path.write_text(
        "- {xyz: [400, 0, 500], quat_xyzw: [0, 0, 0, 1]}\n- {xyz: [300, 10, 600], quat_xyzw: [0, 0, 0, 1]}\n"
    )
    with pytest.raises(
        CalibrationError,
        match=r"every flange position is 640\.\.671 from the base: the translations look like millimetres; give metres",
    ):
        load_poses(path)
    path.write_text("- {matrix: [[1, 0, 0, 0], [0, 1, 0.1, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}\n")
    with pytest.raises(CalibrationError, match="entry 1 is not a rigid 4x4 transform"):
        load_poses(path)
    path.write_text("- {joints: [0, 90, -45]}\n")
    with pytest.raises(
        CalibrationError, match="a joint value of 90 looks like degrees; give radians"
    ):
        load_poses(path)


@pytest.mark.parametrize(
    ("name", "text", "match"),
    [
        ("p.yaml", "[]", "must hold a non-empty list of poses"),
        (
            "p.yaml",
            "- [1, 2, 3]",
            r"entry 1 must be a mapping with xyz \+ quat_xyzw, matrix \(4x4\) or joints",
        ),
        (
            "p.yaml",
            "- {xyz: [0, 0, 0.5], quat: [0, 0, 0, 1]}",
            r"entry 1 needs matrix \(4x4\) or xyz \+ quat_xyzw, got keys \['quat', 'xyz'\]",
        ),
        (
            "p.yaml",
            "- {joints: [0.1], xyz: [0, 0, 0.5], quat_xyzw: [0, 0, 0, 1]}",
            "gives both joints and a pose",
        ),
        (
            "p.yaml",
            "- {joints: [0.1, 0.2]}\n- {joints: [0.1]}",
            r"joint vectors differ in length \[1, 2\]",
        ),
        (
            "p.yaml",
            "- {joints: [0.1], image: a}\n- {joints: [0.1]}",
            r"some entries name their image and others do not \(.*entry 2\)",
        ),
        (
            "p.yaml",
            "joint_names: [a, b]\nposes: [{joints: [0.1]}]",
            "2 joint_names for 1 joint values",
        ),
        (
            "p.yaml",
            "- {image: a, joints: [0.1]}\n- {image: a, joints: [0.2]}",
            r"images named more than once: \['a'\]",
        ),
        (
            "p.yaml",
            "- {matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}",
            "matrix must be 4x4 .rows of 4., got 16 numbers",
        ),
        ("p.csv", "x,y,z,qx,qy,qz\n0,0,0,0,0,0\n", r"missing \['qw'\], unknown \[\]"),
        ("p.csv", "x,y,z,qx,qy,qz,qw,extra\n0,0,0,0,0,0,1,0\n", r"unknown \['extra'\]"),
        (
            "p.csv",
            "x,y,z,qx,qy,qz,qw\n0.1,0.2,0.3,0,0,0,1\n0.1,0.2,0.3,abc,0,0,1\n",
            r"line 3, column qx: 'abc' is not a number",
        ),
        ("p.csv", "x,y,z,qx,qy,qz,qw\n0.1,0.2,0.3,0,0,1\n", "line 2: 6 values for 7 columns"),
        (
            "p.csv",
            "j1,j2,j4\n0,0,0\n",
            r"numbered joint columns must run 1..N .* got \['j1', 'j2', 'j4'\]",
        ),
        (
            "p.csv",
            "image,stamp\na,1\n",
            r"has no pose columns .* and no joint columns .*header: \['image', 'stamp'\]",
        ),
        ("p.csv", "j1,J1\n0,0\n", r"columns \['j1'\] appear more than once"),
        ("p.csv", "j1,j2\n", "needs a header line and at least one row"),
        (
            "p.txt",
            "1 2 3",
            r"unknown format '\.txt'; valid: \.yaml, \.yml, \.json, \.csv, or a folder",
        ),
    ],
)
def test_pose_file_errors(tmp_path: Path, name: str, text: str, match: str) -> None:
    path = tmp_path / name
    path.write_text(text + "\n")
    with pytest.raises(CalibrationError, match=rf"poses file .*{match}"):
        load_poses(path)


def test_pose_count_and_folder_errors(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("- {joints: [0.1]}\n- {joints: [0.2]}\n- {joints: [0.3]}\n")
    with pytest.raises(
        CalibrationError, match=r"p\.yaml: 3 poses for 4 images: give one per image"
    ):
        load_poses(path, count=4)
    with pytest.raises(CalibrationError, match=r"poses file .*missing\.yaml does not exist"):
        load_poses(tmp_path / "missing.yaml")
    folder = tmp_path / "poses"
    folder.mkdir()
    with pytest.raises(
        CalibrationError, match=r"holds no pose files: give one .yaml, .json or .txt per image"
    ):
        load_poses(folder)
    (folder / "a.txt").write_text("1 2 3 4 5")
    with pytest.raises(
        CalibrationError,
        match=r"pose file .*a\.txt holds 5 numbers; a pose text file holds 16 .* or 7",
    ):
        load_poses(folder)
    (folder / "a.txt").write_text("0.1 0.2 0.3 0 0 zero 1")
    with pytest.raises(CalibrationError, match=r"a\.txt: 'zero' is not a number"):
        load_poses(folder)
    (folder / "a.yaml").write_text("xyz: [0, 0, 0.5]\nquat_xyzw: [0, 0, 0, 1]\n")
    with pytest.raises(
        CalibrationError,
        match=r"a\.(txt|yaml) and a\.(txt|yaml) both give the pose of image a: keep one",
    ):
        load_poses(folder)


def test_flange_poses_needs_one_kind() -> None:
    with pytest.raises(CalibrationError, match="exactly one of T_base_flange or joints"):
        FlangePoses()
    with pytest.raises(CalibrationError, match="exactly one of T_base_flange or joints"):
        FlangePoses(T_base_flange=EXPECTED, joints=np.zeros((3, 6)))
    with pytest.raises(CalibrationError, match=r"T_base_flange must be \(N, 4, 4\)"):
        FlangePoses(T_base_flange=np.zeros((3, 3, 3)))


def test_order_by_images() -> None:
    poses = FlangePoses(
        joints=np.arange(4.0).reshape(4, 1), names=("img3.png", "img1", "img2.jpg", "spare")
    )
    images = [Path("shots/img1.png"), Path("shots/img2.jpg"), Path("shots/img3.png")]
    ordered = order_by_images(poses, images)
    assert ordered.names == ("img1", "img2.jpg", "img3.png")
    np.testing.assert_array_equal(_q(ordered), [[1.0], [2.0], [0.0]])
    with pytest.raises(
        CalibrationError,
        match=r"no pose for 2 of 4 images: img4.png, img5.png; poses name images img3.png, img1",
    ):
        order_by_images(poses, [*images[:2], Path("img4.png"), Path("img5.png")])
    twice = FlangePoses(joints=np.zeros((2, 1)), names=("img1", "x"))
    with pytest.raises(CalibrationError, match="pose 'img1' matches two images"):
        order_by_images(twice, [Path("img1.png"), Path("img1.jpg")])
    unnamed = FlangePoses(joints=np.zeros((2, 1)))
    assert order_by_images(unnamed, images[:2]) is unnamed
    with pytest.raises(CalibrationError, match="2 poses for 3 images: give one per image"):
        order_by_images(unnamed, images)


# -- round trips ----------------------------------------------------------------------------

unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=20, deadline=None)
@given(
    xyz=st.lists(st.tuples(unit, unit, unit), min_size=1, max_size=4),
    rpy=st.lists(st.tuples(unit, unit, unit), min_size=4, max_size=4),
)
def test_pose_formats_round_trip(
    xyz: list[tuple[float, float, float]], rpy: list[tuple[float, float, float]]
) -> None:
    """The same poses written as YAML, CSV and a folder of TXT/JSON files read back alike."""
    Ts = [
        from_xyz_rpy(np.array(p) * 2.0, np.array(a) * 3.0) for p, a in zip(xyz, rpy, strict=False)
    ]
    quats = [Rotation.from_matrix(T[:3, :3]).as_quat() for T in Ts]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        entries = [
            {"image": f"i{k}.png", "xyz": T[:3, 3].tolist(), "quat_xyzw": q.tolist()}
            for k, (T, q) in enumerate(zip(Ts, quats, strict=True))
        ]
        (root / "p.yaml").write_text(json.dumps(entries))  # JSON is YAML
        rows = [
            f"i{k}.png," + ",".join(repr(float(v)) for v in [*T[:3, 3], *q])
            for k, (T, q) in enumerate(zip(Ts, quats, strict=True))
        ]
        (root / "p.csv").write_text("image,x,y,z,qx,qy,qz,qw\n" + "\n".join(rows))
        folder = root / "poses"
        folder.mkdir()
        for k, T in enumerate(Ts):
            if k % 2:
                (folder / f"i{k}.txt").write_text(" ".join(repr(float(v)) for v in T.ravel()))
            else:
                (folder / f"i{k}.json").write_text(json.dumps({"matrix": T.tolist()}))
        for source in (root / "p.yaml", root / "p.csv", folder):
            poses = load_poses(source, len(Ts))
            np.testing.assert_allclose(_T(poses), Ts, atol=1e-9)
            assert poses.names is not None
            assert [Path(n).stem for n in poses.names] == [f"i{k}" for k in range(len(Ts))]
