"""Position control laws, pure Python (no ROS): shared by the ``controller`` node and the
offline campaign runner."""

from jetpipe_ros.control.pid import SPECS, Pid, PidConfig

__all__ = ["SPECS", "Pid", "PidConfig"]
