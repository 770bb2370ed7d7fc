"""gaide_core.transforms: the conventions (T_a_b maps b into a, quaternions x, y, z, w) and
the accuracy of what the calibration errors are measured with."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaide_core.transforms import (
    apply,
    from_xyz_quat,
    from_xyz_rpy,
    invert,
    is_rigid,
    make_transform,
    rotation_angle,
    to_xyz_quat,
    transform_error,
)


@pytest.fixture
def poses() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    return [
        from_xyz_quat(rng.uniform(-2, 2, 3), Rotation.random(random_state=i).as_quat())
        for i in range(20)
    ]


def test_xyz_quat_round_trips_and_follows_the_ros_order(poses: list[np.ndarray]) -> None:
    for T in poses:
        xyz, quat = to_xyz_quat(T)
        np.testing.assert_allclose(from_xyz_quat(xyz, quat), T, atol=1e-12)
    # (x, y, z, w): a quarter turn about z
    T = from_xyz_quat([1, 2, 3], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    np.testing.assert_allclose(apply(T, np.array([[1.0, 0, 0]])), [[1, 3, 3]], atol=1e-12)


def test_rpy_is_urdf_fixed_axes_xyz() -> None:
    roll, pitch, yaw = 0.3, -0.4, 1.1
    T = from_xyz_rpy([0, 0, 0], [roll, pitch, yaw])
    Rx = Rotation.from_euler("x", roll).as_matrix()
    Ry = Rotation.from_euler("y", pitch).as_matrix()
    Rz = Rotation.from_euler("z", yaw).as_matrix()
    np.testing.assert_allclose(T[:3, :3], Rz @ Ry @ Rx, atol=1e-12)


def test_invert_and_apply_compose(poses: list[np.ndarray]) -> None:
    points = np.random.default_rng(1).normal(size=(5, 3))
    for T_a_b, T_b_c in itertools.pairwise(poses):
        np.testing.assert_allclose(invert(T_a_b) @ T_a_b, np.eye(4), atol=1e-12)
        np.testing.assert_allclose(
            apply(T_a_b @ T_b_c, points), apply(T_a_b, apply(T_b_c, points)), atol=1e-12
        )
        assert is_rigid(T_a_b)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-6, 0.1, 1.0, np.pi / 2, np.pi - 1e-6, np.pi])
def test_rotation_angle_is_accurate_at_every_angle(angle: float) -> None:
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    R = Rotation.from_rotvec(angle * axis).as_matrix()
    assert rotation_angle(R) == pytest.approx(angle, rel=1e-6, abs=1e-15)


def test_transform_error_measures_the_offset_in_metres_and_radians(
    poses: list[np.ndarray],
) -> None:
    T = poses[0]
    nudge = make_transform(Rotation.from_rotvec([0, 0, 2e-4]).as_matrix(), [0.003, 0, 0.004])
    dt, dr = transform_error(T @ nudge, T)
    assert dr == pytest.approx(2e-4, rel=1e-6)
    assert dt == pytest.approx(np.linalg.norm(T[:3, :3] @ [0.003, 0, 0.004]), rel=1e-9)


def test_is_rigid_refuses_what_is_not_a_pose() -> None:
    assert not is_rigid(np.diag([1.0, 1.0, -1.0, 1.0]))  # a reflection
    assert not is_rigid(np.diag([2.0, 1.0, 1.0, 1.0]))  # a scale
    bad_row = np.eye(4)
    bad_row[3, 0] = 0.1
    assert not is_rigid(bad_row)
    assert not is_rigid(np.full((4, 4), np.nan))
    assert not is_rigid(np.eye(3))
