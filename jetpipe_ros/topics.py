"""The signals a rig measures and the topics of the contract (``msg_defs/topics.yaml``) that
carry them, relative as a namespace moves them: the one map the nodes and the bag export
share."""

#: The topic of each signal a rig may measure: the position y [m] on ``joint_states``, the
#: chamber pressures p1, p2 [Pa] on their ``sensor_msgs/FluidPressure`` topics.
SENSOR_TOPICS = {"y": "joint_states", "p1": "chamber1/pressure", "p2": "chamber2/pressure"}
#: The signals a rig may lack (many have no pressure sensor, or one).
OPTIONAL_SENSORS = ("p1", "p2")
