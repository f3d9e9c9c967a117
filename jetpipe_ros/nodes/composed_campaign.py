"""composed_campaign: actuator_sim, controller and id_recorder in one process, in lock-step.

The three nodes of the distributed set-up (the same classes, names, parameters and topics),
composed in one process on one executor, as a component container would: messages between them
stay inside the process (Fast DDS delivers them without a transport), which is what makes a
lock-step campaign several times faster than with three processes, where moving the 8-10
messages of each simulated millisecond between processes dominates. The topics remain on the
ROS graph, so other processes can still echo or record them.

The simulator is forced to ``time_mode: sim`` and ``lockstep: true``; everything else comes
from the parameters as for the separate executables. All nodes of the process see global
``-p name:=value`` overrides, so give each parameter to its node:

    ros2 run jetpipe_ros composed_campaign --ros-args --params-file config/actuator.yaml \\
        --params-file config/controller.yaml -p id_recorder:bag:=bags/run1

The process exits when the campaign is done (status 0), on Ctrl-C/SIGTERM (the bag closed with
everything up to the signal), with 1 if a node cannot be reached, 2 on bad parameters. To run a
campaign against your own controller or another simulator, use the separate executables.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from rclpy.parameter import Parameter

from jetpipe_ros.nodes import actuator_sim, controller, id_recorder, process

NAME = "composed_campaign"
#: What the simulator must be in a composed campaign, whatever the parameter files say.
SIMULATOR = [Parameter("time_mode", value="sim"), Parameter("lockstep", value=True)]


def main(args: Sequence[str] | None = None) -> int:
    """Run the campaign; 0 when done or stopped, 1 if unreachable, 2 on bad parameters."""
    return process.run_nodes(
        NAME, args,
        [(actuator_sim.NODE_NAME, lambda: actuator_sim.ActuatorSim(parameter_overrides=SIMULATOR)),
         (controller.NODE_NAME, controller.Controller),
         (id_recorder.NODE_NAME, id_recorder.Recorder)],
        work=lambda nodes, executor, stop: id_recorder.run(nodes[2], executor, stop),
        finish=lambda nodes: nodes[0].report(final=True))


if __name__ == "__main__":
    sys.exit(main())
