"""ROS 2 nodes: thin shells that load parameters, call the model and move messages.

``interface`` holds the topic contract, ``parameters`` declares a parameter schema on a node,
``pacing`` decides how many samples are due per timer tick, ``process`` holds the executables'
signal handling and spin loop, ``domain`` reserves a ROS domain per test or benchmark run; the
nodes are ``actuator_sim`` (the simulator), ``controller``
(position PID) and ``id_recorder`` (campaigns recorded to bags), and ``composed_campaign`` runs
all three in one process for fast lock-step campaigns.
"""
