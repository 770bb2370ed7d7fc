"""The robot of a config file and its sphere model, as every command and worker loads them."""

from __future__ import annotations

from planning.robot_model import RobotModel, load_robot
from planning.sphere_model import SphereModel
from planning.spherize import generate_spheres


def robot_and_spheres(config: str | None) -> tuple[RobotModel, SphereModel]:
    """The robot of ``config`` (default UR5) and its sphere model (generated if the config
    names no sphere file)."""
    robot = load_robot(config)
    if robot.config.spheres is not None:
        spheres = SphereModel.load_for(robot.config.spheres, robot)
    else:
        spheres = generate_spheres(robot)
    spheres.check_against(robot)
    return robot, spheres
