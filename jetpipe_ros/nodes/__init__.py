"""ROS 2 nodes: thin shells that load parameters, call the model and move messages.

``interface`` holds the topic contract, ``parameters`` declares a parameter schema on a node,
``pacing`` decides how many samples are due per timer tick, and ``actuator_sim`` is the
simulator node.
"""
