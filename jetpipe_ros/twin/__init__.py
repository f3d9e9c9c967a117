"""The model beside the hardware: fed the actuator's measured samples live, it predicts them
with short-horizon restarts, judges the gap per signal against the measured noise floor
(OK / WARN / ERROR), keeps the latest samples for a capture, and follows diagnoses over time.
No ROS here: the ``gap_monitor`` node is a shell over it."""

from jetpipe_ros.twin.gap import GapWindow, Level, SignalGap
from jetpipe_ros.twin.monitor import Counters, Settings, Twin
from jetpipe_ros.twin.stepper import Stepper

__all__ = ["Counters", "GapWindow", "Level", "Settings", "SignalGap", "Stepper", "Twin"]
