"""Here (with Pinocchio): what training needs of the robot, for a machine without it."""

import pickle
import sys

from planning.neural.checkpoint import robot_signature
from planning.neural.embodiment import RobotCloud, build_embodiment
from planning.robot_setup import robot_and_spheres

robot, _ = robot_and_spheres(None)
emb = build_embodiment(robot)
cloud = RobotCloud(robot, emb)
cloud._fk._model = cloud._fk._data = None  # Pinocchio objects: not needed by points()
bundle = {
    "embodiment": emb,
    "robot_cloud": cloud,
    "signature": robot_signature(robot),
    "lower": robot.lower,
    "upper": robot.upper,
    "dof": robot.dof,
}
with open(sys.argv[1], "wb") as f:
    pickle.dump(bundle, f, protocol=4)
print("bundle", emb.n_points, emb.n_tokens, robot.dof)
