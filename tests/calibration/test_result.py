from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from calibration.result import (
    CalibrationResult,
    FrameResidual,
    MethodResult,
    Mode,
    Setup,
    Spread,
    Uncertainty,
    load_calibration,
)
from calibration.ros_export import Frames, handeye_yaml, save_handeye_yaml, static_transform_command
from gaide_core.errors import CalibrationError
from gaide_core.transforms import make_transform

finite = st.floats(-10.0, 10.0, allow_nan=False)
positive = st.floats(0.0, 100.0, allow_nan=False)


@st.composite
def poses(draw: st.DrawFn) -> np.ndarray:  # type: ignore[type-arg]
    q = np.array(draw(st.lists(st.floats(-1, 1), min_size=4, max_size=4)))
    q = q if np.linalg.norm(q) > 0.1 else np.array([0.0, 0.0, 0.0, 1.0])
    t = np.array(draw(st.lists(finite, min_size=3, max_size=3)))
    return make_transform(Rotation.from_quat(q).as_matrix(), t)


frames = st.builds(
    FrameResidual,
    index=st.integers(0, 10_000),
    stamp_ns=st.none() | st.integers(0, 2**63 - 1),
    rms_px=st.none() | positive,
    used=st.booleans(),
    reason=st.text(max_size=40),
)
methods = st.builds(
    MethodResult, name=st.sampled_from(["tsai", "park"]), T_base_cam=poses(), rms_px=positive
)


@st.composite
def results(draw: st.DrawFn) -> CalibrationResult:
    fx = draw(st.floats(100, 2000))
    return CalibrationResult(
        mode=draw(st.sampled_from(Mode)),
        T_base_cam=draw(poses()),
        K=np.array([[fx, 0, draw(positive)], [0, fx * 1.01, draw(positive)], [0, 0, 1]]),
        D=np.array(draw(st.lists(st.floats(-1, 1), min_size=5, max_size=5))),
        width=draw(st.integers(1, 4096)),
        height=draw(st.integers(1, 4096)),
        reprojection_rms_px=draw(positive),
        frames=tuple(draw(st.lists(frames, max_size=5))),
        methods=tuple(draw(st.lists(methods, max_size=3))),
        spread=draw(st.none() | st.builds(Spread, positive, positive)),
        T_flange_target=draw(st.none() | poses()),
        setup=draw(st.none() | st.sampled_from(Setup)),
        uncertainty=draw(
            st.none()
            | st.builds(
                Uncertainty,
                positive,
                positive,
                st.tuples(positive, positive, positive),
                st.tuples(positive, positive, positive),
            )
        ),
        T_flange_cam=draw(st.none() | poses()),
        T_base_target=draw(st.none() | poses()),
        flange_frame=draw(st.none() | st.just("tool0")),
        target=draw(st.none() | st.just({"type": "tag36h11", "id": 3, "size": 0.08})),
    )


@settings(max_examples=60, deadline=None)
@given(results())
def test_yaml_round_trip(result: CalibrationResult) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        back = load_calibration(result.save_yaml(Path(tmp) / "calib.yaml"))
    assert back.mode == result.mode
    assert np.array_equal(back.T_base_cam, result.T_base_cam)
    assert np.array_equal(back.K, result.K) and np.array_equal(back.D, result.D)
    assert (back.width, back.height) == (result.width, result.height)
    assert back.reprojection_rms_px == result.reprojection_rms_px
    assert back.frames == result.frames
    assert [m.name for m in back.methods] == [m.name for m in result.methods]
    for a, b in zip(back.methods, result.methods, strict=True):
        assert np.array_equal(a.T_base_cam, b.T_base_cam) and a.rms_px == b.rms_px
    assert back.spread == result.spread
    for key in ("T_flange_target", "T_flange_cam", "T_base_target"):
        mine, theirs = getattr(result, key), getattr(back, key)
        assert (theirs is None) if mine is None else np.array_equal(theirs, mine)
    if result.setup is None and result.mode is Mode.HAND_EYE:
        assert back.setup is Setup.EYE_TO_HAND  # files from before eye-in-hand
    else:
        assert back.setup == result.setup
    assert back.uncertainty == result.uncertainty
    assert back.flange_frame == result.flange_frame
    assert back.target == result.target


def test_ros_exports_publish_the_transform_that_holds(tmp_path: Path) -> None:
    T_base_cam = make_transform(Rotation.from_euler("z", 0.5).as_matrix(), np.array([1.0, 0, 0.5]))
    T_flange_cam = make_transform(np.eye(3), np.array([0.0, 0.05, 0.1]))
    base = dict(
        T_base_cam=T_base_cam,
        K=np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]]),
        D=np.zeros(5),
        width=640,
        height=480,
        reprojection_rms_px=0.2,
        frames=(),
    )
    frames = Frames("base_link", "tool0", "cam_optical")
    fixed = CalibrationResult(mode=Mode.FIXED, **base)  # type: ignore[arg-type]
    line = static_transform_command(fixed, frames)
    assert line.startswith("ros2 run tf2_ros static_transform_publisher --x 1 --y 0 --z 0.5")
    assert line.endswith("--frame-id base_link --child-frame-id cam_optical")
    eih = CalibrationResult(
        mode=Mode.HAND_EYE,
        setup=Setup.EYE_IN_HAND,
        T_flange_cam=T_flange_cam,
        **base,  # type: ignore[arg-type]
    )
    data = yaml.safe_load(handeye_yaml(eih, frames))
    assert data["parameters"]["calibration_type"] == "eye_in_hand"
    assert data["parent_frame"] == "tool0"
    assert data["transform"]["translation"] == {"x": 0.0, "y": 0.05, "z": 0.1}
    assert data["transform"]["rotation"]["w"] == pytest.approx(1.0)
    assert "--frame-id tool0" in static_transform_command(eih, frames)
    path = save_handeye_yaml(eih, frames, tmp_path / "he.yaml")
    text = path.read_text()
    assert text.startswith("# ros2 run tf2_ros") and yaml.safe_load(text) == data


def _good(tmp_path: Path) -> dict:  # type: ignore[type-arg]
    result = CalibrationResult(
        mode=Mode.FIXED,
        T_base_cam=make_transform(
            Rotation.from_euler("x", 2.0).as_matrix(), np.array([0.1, 0.2, 1.0])
        ),
        K=np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]]),
        D=np.zeros(5),
        width=640,
        height=480,
        reprojection_rms_px=0.2,
        frames=(FrameResidual(0, 5, 0.2, True),),
    )
    out_dir = tmp_path / "out"
    path = result.save_yaml(out_dir / "calib.yaml")
    data = yaml.safe_load(path.read_text())
    assert set(data) >= {
        "T_base_cam",
        "intrinsics",
        "reprojection_rms_px",
        "frames",
        "methods",
        "spread",
        "mode",
    }
    assert set(data["T_base_cam"]) == {"matrix", "xyz", "quat_xyzw"}
    assert list(out_dir.iterdir()) == [path]  # the temporary file was renamed away
    return data  # type: ignore[no-any-return]


def _write(tmp_path: Path, data: object) -> Path:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_corrupt_files(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match="does not exist"):
        load_calibration(tmp_path / "none.yaml")
    bad = tmp_path / "syntax.yaml"
    bad.write_text("T_base_cam: {matrix: [[1, 0]\nmode: [")
    with pytest.raises(CalibrationError, match="not valid YAML"):
        load_calibration(bad)
    with pytest.raises(CalibrationError, match="must hold a YAML mapping"):
        load_calibration(_write(tmp_path, [1, 2, 3]))

    data = _good(tmp_path)
    del data["T_base_cam"]
    with pytest.raises(CalibrationError, match="lacks the key 'T_base_cam'"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["T_base_cam"]["matrix"][0][0] = 1.5
    with pytest.raises(CalibrationError, match="not a rigid transform"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["T_base_cam"]["matrix"] = [[1, 0, 0], [0, 1, 0]]
    with pytest.raises(CalibrationError, match=r"\(4, 4\) finite numbers"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["T_base_cam"]["xyz"] = [0.1, 0.2, 1.1]
    with pytest.raises(CalibrationError, match="disagree with matrix"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["mode"] = "eye_in_hand"
    with pytest.raises(CalibrationError, match="valid: \\['fixed', 'hand_eye'\\]"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["frames"] = [{"index": 0}]
    with pytest.raises(CalibrationError, match="malformed"):
        load_calibration(_write(tmp_path, data))

    data = _good(tmp_path)
    data["intrinsics"]["K"] = "fx=600"
    with pytest.raises(CalibrationError, match=r"intrinsics\.K"):
        load_calibration(_write(tmp_path, data))


def test_result_refuses_non_rigid() -> None:
    with pytest.raises(CalibrationError, match="not a rigid"):
        CalibrationResult(
            mode=Mode.FIXED,
            T_base_cam=np.diag([1.0, 1.0, -1.0, 1.0]),
            K=np.eye(3),
            D=np.zeros(5),
            width=1,
            height=1,
            reprojection_rms_px=0.0,
            frames=(),
        )
