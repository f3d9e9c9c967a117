"""The jet-pipe servo actuator model: pure Python and numba, no ROS.

Physics by subsystem in ``valve``, ``flow``, ``chamber`` and ``friction``; the compiled
integration loop in ``kernel``; parameters and effects in ``params``; the assembled model in
``actuator``.
"""

from jetpipe_ros.model.actuator import (Actuator, Trace, build_constants, compile_kernel,
                                        simulate)
from jetpipe_ros.model.errors import ParameterError
from jetpipe_ros.model.params import EFFECTS, SPECS, ModelParams, load_params

__all__ = [
    "EFFECTS",
    "SPECS",
    "Actuator",
    "ModelParams",
    "ParameterError",
    "Trace",
    "build_constants",
    "load_params",
    "compile_kernel",
    "simulate",
]
