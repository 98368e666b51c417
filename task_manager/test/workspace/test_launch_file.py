"""The launch file for full ROS 2 installs parses and declares its params_file argument.

`launch` and `launch_ros` are not on PyPI, so the file is checked without running it.
"""

import ast
from pathlib import Path

LAUNCH_FILE = Path(__file__).resolve().parents[2] / 'launch' / 'task_manager.launch.py'


def test_launch_file_defines_the_description_with_a_params_file_argument() -> None:
    tree = ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))

    functions = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)}
    assert 'generate_launch_description' in functions
    assert {'params_file', 'task_manager', 'task-manager'} <= strings
