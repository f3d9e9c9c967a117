"""rosbag2 bags in MCAP storage, written and read with ``rosbags`` (no ROS install needed):
the recorder's writer, and the export of a campaign bag to a dataset (``jetpipe export``)."""

from jetpipe_ros.bag.export import BagError, export_bag
from jetpipe_ros.bag.writer import EVENTS_TOPIC, METADATA_VERSION, BagWriter

__all__ = ["EVENTS_TOPIC", "METADATA_VERSION", "BagError", "BagWriter", "export_bag"]
