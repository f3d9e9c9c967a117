"""jetpipe_ros: a ROS 2 emulation of a jet-pipe electro-pneumatic servo actuator."""

__version__ = "0.2.0"

from pathlib import Path as _Path

from jetpipe_ros.compiled_cache import refresh as _refresh

# Before any compiled function loads: numba's cache misses changes in the modules a cached
# function calls (compiled_cache).
_refresh(_Path(__file__).parent)
