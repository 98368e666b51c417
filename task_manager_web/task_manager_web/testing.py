"""Helpers of the gateway's tests and benchmarks: the gateway run as users do."""

import re
import sys
from pathlib import Path

from task_manager.testing.process import NodeProcess

GATEWAY_EXECUTABLE = str(Path(sys.executable).with_name('task-manager-web'))
DASHBOARD_LINE = r'dashboard: (?P<url>http://\S+)/\?token=(?P<token>\S+)'
START_TIMEOUT_SEC = 20.0


class GatewayProcess(NodeProcess):
    """`task-manager-web --port 0 --token-file F [args]`; its URL and token once it listens."""

    def __init__(self, token_file: Path, *args: str) -> None:
        super().__init__(
            None,
            command=[GATEWAY_EXECUTABLE, '--port', '0', '--token-file', str(token_file), *args],
        )
        match = re.search(DASHBOARD_LINE, self.wait_for_log(DASHBOARD_LINE, START_TIMEOUT_SEC))
        assert match is not None
        self.url = match['url']
        self.token = match['token']
