"""Execution: Ruckig time parameterization that keeps the checked path, exports a controller
can run (CSV, JSON, ROS1/ROS2 bags), PyBullet simulation with the controller output logged,
and comparison of a plan with a controller log.

Depends on ``core`` and ``planning`` only (robot model, collision checker, worlds).
"""
