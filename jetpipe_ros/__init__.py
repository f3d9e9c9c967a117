"""jetpipe_ros: a ROS 2 emulation of a jet-pipe electro-pneumatic servo actuator."""

__version__ = "0.2.0"
