"""Planning: the robot (Pinocchio model, kinematics, IK, sphere model), worlds and collision
checking (the numpy reference and the compiled core), the task families, problem files and
MoveIt imports, the planners (OMPL baselines, the compiled RRT-Connect, the neural
bidirectional planner), path processing and the benchmark harness.

Depends on ``gaide_core`` only. Modules import their heavy libraries (Pinocchio, OMPL,
torch) themselves, so importing one module costs only what it needs.
"""

__all__ = [
    "bench_collision",
    "checker",
    "collision",
    "compiled",
    "distance_field",
    "families",
    "family_names",
    "harness",
    "harness_report",
    "ik",
    "kinematics",
    "mesh_reference",
    "moveit_import",
    "neural",
    "neural_planner",
    "ompl_planners",
    "oracle",
    "path_check",
    "path_ops",
    "planner",
    "plot",
    "primitives",
    "problem",
    "registry",
    "robot_config",
    "robot_model",
    "robot_names",
    "robot_setup",
    "rrtc",
    "scene_views",
    "setup_assistant",
    "sphere_model",
    "spherize",
    "world",
]
