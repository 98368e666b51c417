"""NodeLog (rclpy_tools/log.py), the one way the node and the client write log lines: a line
has the severity, the logger's name and the origin rclpy's own logger gives it (function,
file, line of the caller), and a level below the logger's writes nothing. In a process of its
own, so that rcutils reads the output format set for it."""

import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros
OUTPUT_FORMAT = '{severity}|{name}|{function_name}|{line_number}|{message}'

SCRIPT = textwrap.dedent(
    """
    import rclpy
    from rclpy.logging import LoggingSeverity

    from task_manager.rclpy_tools.log import NodeLog

    def write(log, rclpy_logger):
        log.warning('from NodeLog')
        rclpy_logger.warning('from rclpy')
        log.debug('not shown')
        log.child('part').error('from a part')

    rclpy.init()
    node = rclpy.create_node('node_log_test')
    node.get_logger().set_level(LoggingSeverity.INFO)
    write(NodeLog.of(node), node.get_logger())
    node.destroy_node()
    rclpy.shutdown()
    """
)


def test_a_line_has_the_severity_name_and_origin_rclpy_gives_it() -> None:
    environment = {
        **os.environ,
        'RCUTILS_CONSOLE_OUTPUT_FORMAT': OUTPUT_FORMAT,
        'RCUTILS_COLORIZED_OUTPUT': '0',
    }
    finished = subprocess.run(
        [sys.executable, '-c', SCRIPT], env=environment, capture_output=True, text=True, timeout=60
    )
    assert finished.returncode == 0, finished.stderr
    lines = [line.split('|') for line in finished.stderr.splitlines() if line.count('|') == 4]

    assert lines == [
        ['WARN', 'node_log_test', 'write', '8', 'from NodeLog'],
        ['WARN', 'node_log_test', 'write', '9', 'from rclpy'],
        ['ERROR', 'node_log_test.part', 'write', '11', 'from a part'],
    ]
