"""Helpers of the bridge's tests and benchmarks: the bridge run as users run it."""

import sys
from pathlib import Path

from task_manager.testing.process import NodeProcess

BRIDGE_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-mqtt'))
CONNECTED_LINE = r'connected to the broker'
START_TIMEOUT_SEC = 20.0
ROBOT = 'robot1'
"""The robot of the tests with one robot."""


class BridgeProcess(NodeProcess):
    """`task-manager-mqtt --robot-id R --broker-url U --state-file F [args]`."""

    def __init__(
        self, robot_id: str, broker_url: str, state_file: Path, *args: str, wait: bool = True
    ) -> None:
        """`wait`: until it is connected to the broker."""
        command = [
            BRIDGE_EXECUTABLE,
            '--robot-id',
            robot_id,
            '--broker-url',
            broker_url,
            '--state-file',
            str(state_file),
            *args,
        ]
        super().__init__(None, command=command)
        if wait:
            self.wait_for_log(CONNECTED_LINE, START_TIMEOUT_SEC)
