"""Batched forward kinematics of joint frames and points carried by links (numpy).

Pinocchio evaluates one configuration per call; collision checking wants ten thousand at
once, so the same joint chain is evaluated here as array operations over the batch. The
result is checked against Pinocchio in the tests and by ``gaide bench collision``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from gaide_core.errors import RobotModelError
from gaide_core.types import Array
from planning.compiled.trig import sincos_array
from planning.robot_model import RobotModel

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


class BatchKinematics:
    """Joint poses of a batch of configurations: ``R`` (B, J, 3, 3) and ``t`` (B, J, 3) in
    the world frame, J = joints including the universe (index 0)."""

    def __init__(self, robot: RobotModel) -> None:
        model = robot.model
        self.njoints = int(model.njoints)
        self.parents = [int(model.parents[j]) for j in range(self.njoints)]
        self.placements_R = np.stack(
            [model.jointPlacements[j].rotation for j in range(self.njoints)]
        )
        self.placements_t = np.stack(
            [model.jointPlacements[j].translation for j in range(self.njoints)]
        )
        self.axes = np.zeros((self.njoints, 3))
        self.prismatic = np.zeros(self.njoints, bool)
        self.idx_q = [int(model.joints[j].idx_q) for j in range(self.njoints)]
        for j in range(1, self.njoints):
            joint = model.joints[j]
            short = joint.shortname()
            if short in ("JointModelRX", "JointModelRY", "JointModelRZ"):
                self.axes[j] = _AXES[short[-1]]
            elif short in ("JointModelPX", "JointModelPY", "JointModelPZ"):
                self.axes[j] = _AXES[short[-1]]
                self.prismatic[j] = True
            elif short == "JointModelRevoluteUnaligned":
                self.axes[j] = np.asarray(joint.extract().axis, float)
            elif short == "JointModelPrismaticUnaligned":
                self.axes[j] = np.asarray(joint.extract().axis, float)
                self.prismatic[j] = True
            else:
                raise RobotModelError(
                    f"joint '{model.names[j]}' has type {short}; batched kinematics supports "
                    "revolute and prismatic joints"
                )
        self.T_world_base = robot.T_world_base
        self._model, self._data = robot.model, robot.model.createData()
        self._base_identity = bool(np.allclose(robot.T_world_base, np.eye(4)))

    def joint_poses(self, Q: Array) -> tuple[list[Array], list[Array]]:
        """World rotation (B, 3, 3) and translation (B, 3) of every joint frame, as lists
        indexed by joint (0: the universe). Kept as separate contiguous arrays: slicing a
        (B, J, 3, 3) block per joint costs more than the products themselves."""
        B = Q.shape[0]
        dtype = Q.dtype
        R: list[Array] = [np.broadcast_to(self.T_world_base[:3, :3].astype(dtype), (B, 3, 3))]
        t: list[Array] = [np.broadcast_to(self.T_world_base[:3, 3].astype(dtype), (B, 3))]
        for j in range(1, self.njoints):
            p = self.parents[j]
            # parent pose composed with the fixed placement of joint j in its parent
            Rp = R[p] @ self.placements_R[j].astype(dtype)
            tp = t[p] + R[p] @ self.placements_t[j].astype(dtype)
            q = Q[:, self.idx_q[j]]
            axis = self.axes[j].astype(dtype)
            if self.prismatic[j]:
                R.append(Rp)
                t.append(tp + (Rp @ axis) * q[:, None])
            else:
                R.append(Rp @ _axis_rotation(axis, q))
                t.append(tp)
        return R, t

    def points_one(self, q: Array, joint_ids: npt.NDArray[np.int64], local: Array) -> Array:
        """World positions (P, 3) for one configuration q (dof,): Pinocchio's forward pass is
        one C++ call, where the batched path costs ~0.3 ms of numpy overhead per call."""
        pin.forwardKinematics(self._model, self._data, q)
        oMi = self._data.oMi
        R = np.array([oMi[int(j)].rotation for j in range(self.njoints)])
        t = np.array([oMi[int(j)].translation for j in range(self.njoints)])
        pts = np.einsum("pij,pj->pi", R[joint_ids], local) + t[joint_ids]
        if self._base_identity:
            return pts
        return pts @ self.T_world_base[:3, :3].T + self.T_world_base[:3, 3]

    def points(self, Q: Array, joint_ids: npt.NDArray[np.int64], local: Array) -> Array:
        """World positions (B, P, 3) of points ``local`` (P, 3) fixed in the frames of joints
        ``joint_ids`` (P,), for configurations Q (B, dof)."""
        R, t = self.joint_poses(Q)
        out = np.empty((Q.shape[0], len(joint_ids), 3), Q.dtype)
        for j in np.unique(joint_ids):
            sel = np.flatnonzero(joint_ids == j)
            # (B, 3, 3) @ (3, P) -> (B, 3, P)
            moved = R[j] @ local[sel].T.astype(Q.dtype)
            out[:, sel] = moved.transpose(0, 2, 1) + t[j][:, None, :]
        return out


def _axis_rotation(axis: Array, angle: Array) -> Array:
    """(B, 3, 3) rotations about a unit ``axis`` by ``angle`` (B,) rad (Rodrigues)."""
    s, c = sincos_array(angle)  # the kernels' sine and cosine, bit for bit
    x, y, z = axis
    C = 1.0 - c
    out = np.empty((angle.shape[0], 3, 3), angle.dtype)
    out[:, 0, 0] = c + x * x * C
    out[:, 0, 1] = x * y * C - z * s
    out[:, 0, 2] = x * z * C + y * s
    out[:, 1, 0] = y * x * C + z * s
    out[:, 1, 1] = c + y * y * C
    out[:, 1, 2] = y * z * C - x * s
    out[:, 2, 0] = z * x * C - y * s
    out[:, 2, 1] = z * y * C + x * s
    out[:, 2, 2] = c + z * z * C
    return out


def reference_points(
    robot: RobotModel, q: Array, joint_ids: npt.NDArray[np.int64], local: Array
) -> Array:
    """Pinocchio's answer for :meth:`BatchKinematics.points` at one configuration (P, 3)."""
    pin.forwardKinematics(robot.model, robot.data, q)
    out = np.empty((len(joint_ids), 3))
    for i, (j, p) in enumerate(zip(joint_ids, local, strict=True)):
        out[i] = robot.data.oMi[int(j)].act(p)
    return out @ robot.T_world_base[:3, :3].T + robot.T_world_base[:3, 3]
