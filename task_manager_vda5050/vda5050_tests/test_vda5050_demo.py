"""`make vda5050` as users run it (its launcher, Ctrl-C to stop) and the example it prints."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from task_manager_demo.testing import DemoProcess

REPO = Path(__file__).resolve().parents[2]
READY_TIMEOUT_SEC = 60.0
EXAMPLE_TIMEOUT_SEC = 90.0

pytestmark = pytest.mark.ros


def test_make_vda5050_prints_the_broker_and_the_vehicle_and_the_example_completes_an_order(
    tmp_path: Path,
) -> None:
    demo = DemoProcess(
        'vda5050',
        [sys.executable, '-m', 'task_manager_demo.run_vda5050', '--folder', str(tmp_path)],
    )
    try:
        broker_line = demo.wait_for_line(r'^  broker: ', READY_TIMEOUT_SEC)
        vehicle_line = demo.wait_for_line(r'^  vda5050: ', READY_TIMEOUT_SEC)
        assert re.fullmatch(r'  broker: mqtt://master:\S+@127\.0\.0\.1:\d+', broker_line)
        assert vehicle_line == '  vda5050: uagv/v2/demo/robot1'
        url = broker_line.split(': ', 1)[1]

        example = subprocess.run(
            [sys.executable, str(REPO / 'examples' / 'vda5050_order.py'), '--broker-url', url],
            capture_output=True,
            text=True,
            timeout=EXAMPLE_TIMEOUT_SEC,
            check=False,
        )

        assert example.returncode == 0, example.stdout + example.stderr
        lines = example.stdout.splitlines()
        assert lines[-1] == 'order done'
        assert any('take_photo FINISHED' in line for line in lines), example.stdout
    finally:
        demo.signal_group()
        assert demo.wait_exit(30.0) == 0, demo.output
