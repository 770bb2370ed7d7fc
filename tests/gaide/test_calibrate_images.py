"""`gaide calibrate --images`: photos, an intrinsics file and flange poses instead of a bag."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from gaide.bench_perception import EIH_BOARD, EIH_T_FLANGE_CAM, eye_in_hand_views
from gaide_core.transforms import to_xyz_quat, transform_error
from tests.conftest import run_cli

TARGET = EIH_BOARD.spec()


@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of 9 photos of a fixed board from a camera on the flange, with poses.csv
    (the flange pose per photo, in shuffled order) and intrinsics.json."""
    folder = tmp_path_factory.mktemp("photos")
    images, flanges, K = eye_in_hand_views(np.random.default_rng(5), poses=9)
    rows = ["image,x,y,z,qx,qy,qz,qw"]
    for i, (image, T) in enumerate(zip(images, flanges, strict=True)):
        name = f"shot{i + 1}.png"
        cv2.imwrite(str(folder / name), image)
        xyz, quat = to_xyz_quat(T)
        rows.append(",".join([name, *(f"{v:.10f}" for v in (*xyz, *quat))]))
    header, body = rows[0], rows[1:]
    (folder / "poses.csv").write_text("\n".join([header, *body[::-1]]) + "\n")
    intrinsics = {"width": 848, "height": 480, "K": K.tolist(), "D": [0, 0, 0, 0, 0]}
    (folder / "intrinsics.json").write_text(json.dumps(intrinsics))
    return folder


def _calibrate(photos: Path, out: Path, *extra: str) -> tuple[int, str, str]:
    proc = run_cli(
        "calibrate",
        "--images",
        str(photos / "*.png"),
        "--mode",
        "hand-eye",
        "--setup",
        "eye-in-hand",
        "--poses",
        str(photos / "poses.csv"),
        "-o",
        str(out / "calib.yaml"),
        "--json",
        str(out / "cal.json"),
        *extra,
    )
    return proc.returncode, proc.stdout, proc.stderr


def test_eye_in_hand_from_photos_poses_and_intrinsics(photos: Path, tmp_path: Path) -> None:
    rc, stdout, stderr = _calibrate(
        photos, tmp_path, "--target", TARGET, "--intrinsics", str(photos / "intrinsics.json")
    )
    assert rc == 0, stderr
    figures = json.loads((tmp_path / "cal.json").read_text())
    dt, dr = transform_error(np.array(figures["T_flange_cam"]), EIH_T_FLANGE_CAM)
    assert dt < 0.002 and np.degrees(dr) < 0.2, (dt, np.degrees(dr))
    assert figures["setup"] == "eye_in_hand" and figures["frames_used"] == 9
    assert 0 < figures["std_mm"] < 1.0
    handeye = yaml.safe_load((tmp_path / "calib.handeye.yaml").read_text())
    assert handeye["parameters"]["calibration_type"] == "eye_in_hand"
    assert handeye["parent_frame"] == "tool0"
    assert "ros2 run tf2_ros static_transform_publisher" in stdout
    assert "--frame-id tool0" in figures["static_transform_publisher"]
    saved = yaml.safe_load((tmp_path / "calib.yaml").read_text())
    assert saved["setup"] == "eye_in_hand" and saved["T_flange_cam"]["matrix"]


def test_intrinsics_estimated_from_the_same_photos(photos: Path, tmp_path: Path) -> None:
    rc, _, stderr = _calibrate(photos, tmp_path, "--target", TARGET)
    assert rc == 0, stderr
    figures = json.loads((tmp_path / "cal.json").read_text())
    assert figures["intrinsics_rms_px"] < 0.5
    dt, dr = transform_error(np.array(figures["T_flange_cam"]), EIH_T_FLANGE_CAM)
    assert dt < 0.01 and np.degrees(dr) < 0.5, (dt, np.degrees(dr))


def _refused(photos: Path, tmp_path: Path, *extra: str) -> str:
    """Run a calibration that must fail: exit 4, one line, nothing written."""
    out = tmp_path / "out"
    out.mkdir(parents=True)
    rc, _, stderr = _calibrate(photos, out, "--intrinsics", str(photos / "intrinsics.json"), *extra)
    assert rc == 4, stderr
    assert stderr.count("\n") == 1, stderr
    assert list(out.iterdir()) == []
    return stderr


def test_a_board_of_another_dictionary_is_named(photos: Path, tmp_path: Path) -> None:
    stderr = _refused(photos, tmp_path, "--target", "charuco:7x5,square=0.04,marker=0.03")
    # DICT_6X6_50 holds the board's ids 0-16 and its markers are DICT_6X6_250's first ones.
    assert "found DICT_6X6_50 ids 0-16" in stderr and "DICT_6X6_250" in stderr, stderr
    assert "add dict=DICT_6X6_50" in stderr


def test_bad_inputs_exit_4_and_write_nothing(photos: Path, tmp_path: Path) -> None:
    stderr = _refused(photos, tmp_path / "a", "--target", TARGET.replace("6X6", "9X9"))
    assert "unknown marker dictionary" in stderr
    rows = (photos / "poses.csv").read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(rows[:-1]) + "\n")
    stderr = _refused(photos, tmp_path / "b", "--target", TARGET, "--poses", str(short))
    assert "8 poses for 9 images" in stderr
    two = tmp_path / "two"
    two.mkdir()
    for name in ("shot1.png", "shot2.png"):
        (two / name).write_bytes((photos / name).read_bytes())
    (two / "poses.csv").write_text("\n".join([rows[0], *rows[-2:]]) + "\n")
    (two / "intrinsics.json").write_text((photos / "intrinsics.json").read_text())
    stderr = _refused(two, tmp_path / "c", "--target", TARGET)
    assert "at least 3" in stderr
