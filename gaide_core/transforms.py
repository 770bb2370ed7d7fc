"""Rigid transforms as 4x4 homogeneous matrices.

Convention: ``T_a_b`` is the pose of frame b in frame a, so ``p_a = T_a_b @ p_b``.
Quaternions are ``(x, y, z, w)`` (scipy's and ROS's order). Units: metres, radians.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from gaide_core.types import Array


def make_transform(rotation: Array | None = None, translation: Array | None = None) -> Array:
    """4x4 transform from a (3, 3) rotation matrix and a (3,) translation (m)."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    if translation is not None:
        T[:3, 3] = translation
    return T


def from_xyz_quat(xyz: npt.ArrayLike, quat_xyzw: npt.ArrayLike) -> Array:
    """4x4 transform from a translation (m) and a unit quaternion (x, y, z, w)."""
    return make_transform(
        Rotation.from_quat(np.asarray(quat_xyzw, float)).as_matrix(), np.asarray(xyz, float)
    )


def from_xyz_rpy(xyz: npt.ArrayLike, rpy: npt.ArrayLike) -> Array:
    """4x4 transform from a translation (m) and URDF roll-pitch-yaw (rad, fixed axes XYZ)."""
    rot = Rotation.from_euler("xyz", np.asarray(rpy, float)).as_matrix()
    return make_transform(rot, np.asarray(xyz, float))


def to_xyz_quat(T: Array) -> tuple[Array, Array]:
    """Translation (m) and unit quaternion (x, y, z, w) of a 4x4 transform."""
    return T[:3, 3].copy(), Rotation.from_matrix(T[:3, :3]).as_quat()


def invert(T: Array) -> Array:
    """Inverse of a rigid transform, without a general matrix inverse."""
    R = T[:3, :3]
    return make_transform(R.T, -R.T @ T[:3, 3])


def apply(T: Array, points: Array) -> Array:
    """Transform points (N, 3) by ``T``: returns ``T @ p`` for each row."""
    return points @ T[:3, :3].T + T[:3, 3]


def rotation_angle(R: Array) -> float:
    """Rotation angle (rad, in [0, pi]) of a 3x3 rotation matrix, accurate at every angle
    (scipy's ``Rotation.magnitude``, through the quaternion; the trace formula's arccos
    loses small angles: it returns 0 for 1e-9 rad)."""
    return float(Rotation.from_matrix(np.asarray(R, float)).magnitude())


def transform_error(T_est: Array, T_true: Array) -> tuple[float, float]:
    """Translation error (m) and rotation error (rad) between two transforms."""
    delta = invert(T_true) @ T_est
    return float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])), rotation_angle(delta[:3, :3])


def is_rigid(T: Array, tol: float = 1e-6) -> bool:
    """True if ``T`` is a 4x4 rigid transform (orthonormal rotation, det +1, last row 0001)."""
    T = np.asarray(T)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(
        np.allclose(R.T @ R, np.eye(3), atol=tol)
        and abs(np.linalg.det(R) - 1.0) < tol
        and np.allclose(T[3], [0, 0, 0, 1], atol=tol)
    )
