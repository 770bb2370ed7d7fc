"""Start and goal of a run, as a user writes them, turned into joint vectors.

Forms (``what`` is "start" or "goal"):

- ``recorded``: the robot's joint state recorded in the bag;
- a named configuration of the robot config (``home``);
- ``a,b,c,d,e,f``: one angle per joint (rad);
- ``pose:x,y,z,qx,qy,qz,qw``: an end-effector pose in the base frame (m, unit quaternion);
  ``xyz:x,y,z`` (or ``pose:x,y,z``): a position, with the end-effector orientation of the
  reference configuration (the start for a goal; the recorded state, else ``home``, for a
  start). Poses are solved by collision-free inverse kinematics in the perceived scene,
  choosing the solution nearest the reference configuration.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from gaide_core.errors import ConfigError, PlanningError
from gaide_core.transforms import from_xyz_quat
from gaide_core.types import Array
from planning.checker import endpoint_checker
from planning.collision import CollisionChecker
from planning.ik import IKCfg, solve_ik
from planning.robot_model import RobotModel

FORMS = (
    "'recorded', a named configuration, a,b,c,d,e,f (rad), pose:x,y,z,qx,qy,qz,qw or xyz:x,y,z (m)"
)


class EndpointKind(enum.Enum):
    RECORDED = "recorded"
    NAMED = "named"
    JOINTS = "joints"
    POSE = "pose"


@dataclass(frozen=True)
class Endpoint:
    """A parsed start or goal (not yet solved)."""

    what: str  # "start" or "goal"
    text: str  # as the user wrote it
    kind: EndpointKind
    joints: Array | None = None  # (dof,) rad, for JOINTS and NAMED
    xyz: Array | None = None  # (3,) m, base frame, for POSE
    quat_xyzw: Array | None = None  # (4,) unit quaternion, None: the reference's orientation


@dataclass(frozen=True)
class Resolved:
    """A joint vector for an endpoint, and how it was found."""

    endpoint: Endpoint
    q: Array  # (dof,) rad
    how: str  # for the summary: "recorded", "named home", "IK (3 solutions)", ...


def _numbers(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError as err:
        raise ConfigError(f"{what} '{text}' is not understood; give {FORMS}") from err


def parse_endpoint(text: str, robot: RobotModel, what: str) -> Endpoint:
    """The endpoint ``text`` names (ConfigError listing the valid forms otherwise)."""
    spec = text.strip()
    named = robot.config.named_configurations
    if spec == "recorded":
        return Endpoint(what, spec, EndpointKind.RECORDED)
    if spec in named:
        return Endpoint(what, spec, EndpointKind.NAMED, joints=robot.named_configuration(spec))
    head, sep, rest = spec.partition(":")
    if sep and head in ("pose", "xyz"):
        v = _numbers(rest, what)
        if len(v) not in ((3,) if head == "xyz" else (3, 7)):
            raise ConfigError(
                f"{what} '{spec}': {head}: takes x,y,z"
                + (" or x,y,z,qx,qy,qz,qw" if head == "pose" else "")
                + f" (m, base frame); got {len(v)} numbers"
            )
        quat = None
        if len(v) == 7:
            quat = np.asarray(v[3:])
            norm = float(np.linalg.norm(quat))
            if not 0.9 < norm < 1.1:
                raise ConfigError(
                    f"{what} '{spec}': the quaternion (qx, qy, qz, qw) must be a unit "
                    f"quaternion, its norm is {norm:.3f}"
                )
            quat = quat / norm
        return Endpoint(what, spec, EndpointKind.POSE, xyz=np.asarray(v[:3]), quat_xyzw=quat)
    if sep:
        raise ConfigError(f"{what} '{spec}': unknown form '{head}:'; give {FORMS}")
    if not any(c.isdigit() for c in spec):
        raise ConfigError(
            f"{what} '{spec}' is not a named configuration of the robot "
            f"{sorted(named) or '(none)'}; give {FORMS}"
        )
    q = robot.configuration_from_text(spec, what, ConfigError)
    return Endpoint(what, spec, EndpointKind.JOINTS, joints=q)


def reference_configuration(robot: RobotModel, recorded: Array | None) -> Array:
    """The recorded state, else ``home``, else the middle of the joint limits."""
    if recorded is not None:
        return recorded
    if "home" in robot.config.named_configurations:
        return robot.named_configuration("home")
    return (robot.lower + robot.upper) / 2


def resolve(
    ep: Endpoint,
    checker: CollisionChecker,
    *,
    recorded: Array | None,
    reference: Array,
    rng: np.random.Generator,
    restarts: int,
) -> Resolved:
    """The endpoint's joint vector. Recorded without joint states, or a pose with no
    collision-free IK solution, is a PlanningError naming the endpoint; validity of the
    result is checked by the caller."""
    robot = checker.robot
    if ep.kind is EndpointKind.RECORDED:
        if recorded is None:
            raise PlanningError(
                f"{ep.what} 'recorded': the bag has no joint states (sensor_msgs/JointState); "
                f"give --{ep.what} as {FORMS}"
            )
        return Resolved(ep, np.asarray(recorded, float), "recorded in the bag")
    if ep.kind in (EndpointKind.NAMED, EndpointKind.JOINTS):
        assert ep.joints is not None  # set by parse_endpoint for these kinds
        how = f"named configuration '{ep.text}'" if ep.kind is EndpointKind.NAMED else "joints"
        return Resolved(ep, ep.joints.astype(float), how)
    assert ep.xyz is not None  # set by parse_endpoint for POSE
    T_base_ref = np.linalg.inv(robot.T_world_base) @ robot.frame_pose(reference)
    T_base = T_base_ref.copy() if ep.quat_xyzw is None else from_xyz_quat(ep.xyz, ep.quat_xyzw)
    T_base[:3, 3] = ep.xyz
    T = robot.T_world_base @ T_base
    cfg = IKCfg(restarts=restarts)
    # Solutions with a little room beyond the margin first (certified motions can reach
    # them), then any collision-free one.
    for check, room in ((endpoint_checker(checker), "with room beyond the margin"), (checker, "")):
        sols = solve_ik(robot, T, rng, cfg=cfg, checker=check, seed=reference)
        if sols:
            how = f"IK, nearest of {len(sols)} collision-free solutions {room}".rstrip()
            return Resolved(ep, sols[0], how)
    free = solve_ik(robot, T, rng, cfg=IKCfg(restarts=restarts, max_solutions=1), seed=reference)
    if free:
        why = f"it is reachable, but the solutions found collide ({checker.diagnose(free[0])})"
    else:
        why = "no solution within the joint limits: it is out of reach or the orientation is"
        why += " impossible there"
    raise PlanningError(
        f"{ep.what} '{ep.text}': no collision-free IK solution in {restarts} restarts; {why}"
    )
