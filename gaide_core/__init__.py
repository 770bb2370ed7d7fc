"""Dependency-free foundation shared by every stage (numpy, scipy and rosbags only).

Nothing here imports another package of the project; every stage may import it.

- ``errors``: the exception tree (GaideError and one subclass per stage);
- ``types``: the array aliases; ``transforms``: rigid transforms; ``camera``: intrinsics;
- ``joints``: JointStates, one joint-state series (a bag's /joint_states, a controller log);
- ``ros``: ROS1/ROS2 messages (Messages), JointState series as messages and back, and
  write_bag, one bag writer for every package;
- ``atomic``: atomic file writes (one file, or several files and folders all or none);
- ``settings``: checks of single settings; ``text_io``: safe reading of users' text files;
- ``plan_file``: the plan file (``plan.json``); ``native_output``: silencing C++ libraries.
"""

__all__ = [
    "atomic",
    "camera",
    "errors",
    "joints",
    "native_output",
    "plan_file",
    "ros",
    "settings",
    "text_io",
    "transforms",
    "types",
]
