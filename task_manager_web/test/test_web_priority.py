"""The gateway yields the CPU to the robot: started as users start it, every thread of it runs at
the gateways' nice value (task_manager.cpu_priority); `--nice 0` keeps its starter's."""

import os
from collections.abc import Callable

from task_manager.cpu_priority import GATEWAY_NICENESS
from task_manager.testing.gateway import Robot
from task_manager.testing.process import thread_nice_values
from task_manager_web.testing import GatewayProcess, gateway_client


def test_the_gateway_runs_nicer_than_the_robot_unless_told(
    robot: Robot, start_gateway: Callable[..., GatewayProcess]
) -> None:
    own = os.getpriority(os.PRIO_PROCESS, 0)
    as_users_start_it = start_gateway(nice=None)
    told_zero = start_gateway(nice=0)
    for gateway in (as_users_start_it, told_zero):
        with gateway_client(gateway):  # connected to the node: its DDS threads are running
            pass
    assert thread_nice_values(as_users_start_it.process.pid) == {max(own, GATEWAY_NICENESS)}
    assert thread_nice_values(told_zero.process.pid) == {own}
