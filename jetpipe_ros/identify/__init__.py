"""Parameter identification, the paper's procedures on recorded data (``jetpipe identify``):
the flow map from charge/discharge tests, the valve dynamics from a sine sweep, the hysteresis
loop from slow ramps and the friction planes from regulator-held sliding tests."""

from jetpipe_ros.identify.identify import PROCEDURES, Identification, identify

__all__ = ["PROCEDURES", "Identification", "identify"]
