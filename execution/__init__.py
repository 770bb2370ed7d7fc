"""Execution: Ruckig time parameterization that keeps the checked path, exports a controller
can run (CSV, JSON, ROS1/ROS2 bags, a URScript program, a ros2_control goal), PyBullet
simulation through a servo model of the arm's controller with its output logged, and
comparison of a plan with a controller log.

Depends on ``core`` and ``planning`` only (robot model, collision checker, worlds).

- timing: ``timing_cfg`` (TimingCfg, TimingMode), ``limits`` (JointLimits),
  ``parameterizer`` (the TimeParameterizer protocol), ``ruckig_timing``
  (RuckigParameterizer, time_parameterize), with ``path_input`` (checks), planning's
  ``path_ops`` (string pulling, corner cuts), ``blend`` (waypoint velocities), ``ruckig_segments``
  (moves and their exact states), ``recheck`` (collision re-check of blends);
- results and checks: ``trajectory`` (TimedTrajectory), ``verify`` (limits at 1 kHz,
  distance from the path, swept collisions);
- files: ``trajectory_io`` (CSV, JSON), ``ros_bags`` (JointTrajectory and JointState bags),
  ``joint_log`` (log CSV of a ``gaide_core.joints.JointStates`` series), ``export`` (by
  suffix, all or nothing, with ``gaide_core.atomic``);
- execution: ``sim_cfg`` (SimCfg), ``servo`` (ServoCfg: a real arm's controller), ``sim_world``
  and ``simulate`` (PyBullet), ``compare``
  (plan vs log), ``plots``;
- ``bench_timing``: ``gaide bench timing``.
"""

__all__ = [
    "bench_timing",
    "blend",
    "compare",
    "export",
    "joint_log",
    "limits",
    "parameterizer",
    "path_input",
    "plots",
    "recheck",
    "ros2_goal",
    "ros_bags",
    "ruckig_segments",
    "ruckig_timing",
    "servo",
    "sim_cfg",
    "sim_world",
    "simulate",
    "timing_cfg",
    "trajectory",
    "trajectory_io",
    "urscript",
    "verify",
]
