"""prepare_ros_process: message type supports load without rosidl's code generator, which
stays available on demand. Each case runs in a fresh interpreter (the setup acts on
sys.modules, once per process)."""

import subprocess
import sys

LOAD_A_TYPE_SUPPORT = """
import sys
{setup}
from std_srvs.srv import Trigger
Trigger.__class__.__import_type_support__()
print('lark' in sys.modules)
"""


def _lark_loaded_by_a_type_support(setup: str) -> bool:
    script = LOAD_A_TYPE_SUPPORT.format(setup=setup)
    output = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, check=True, timeout=60
    ).stdout
    return output.split()[-1] == 'True'


def test_a_type_support_loads_without_the_code_generator() -> None:
    # rosidl's own package imports its generator (lark) with every type support...
    assert _lark_loaded_by_a_type_support('')
    # ...and not once the process is prepared
    assert not _lark_loaded_by_a_type_support(
        'from task_manager.process_setup import prepare_ros_process; prepare_ros_process()'
    )


def test_the_code_generator_is_still_there_when_asked_for() -> None:
    script = (
        'from task_manager.process_setup import load_type_supports_without_code_generator as f\n'
        'assert f()\n'
        'assert not f()\n'
        'from rosidl_generator_py import generate_py, import_type_support\n'
        'import rosidl_generator_py.generate_py_impl as impl\n'
        'assert generate_py is impl.generate_py and callable(import_type_support)\n'
    )
    subprocess.run([sys.executable, '-c', script], check=True, timeout=60)
