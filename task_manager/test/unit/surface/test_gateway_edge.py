"""The public surface a gateway stands on: what the web gateway, the MQTT bridge, the VDA 5050
adapter and the fleet console import of `task_manager` is the client, the protocol, the
gateway package, core's values, the process set-up and the nice value
(task_manager/gateway/__init__.py says so), and the contract that keeps them off the node
allows no indirect import."""

import ast
import configparser
from pathlib import Path

REPO = Path(__file__).resolve().parents[4]
GATEWAYS = ('task_manager_web', 'task_manager_mqtt', 'task_manager_vda5050', 'task_manager_console')
EDGE = (
    'task_manager.client',
    'task_manager.protocol',
    'task_manager.gateway',
    'task_manager.core',
    'task_manager.process_setup',
    'task_manager.cpu_priority',
)
TESTING = 'task_manager.testing'
"""Also imported by a gateway's own test fixtures (its testing modules)."""


def _imported(path: Path) -> set[str]:
    """The `task_manager` modules a file imports (`from task_manager import x`: task_manager.x)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            is_root = node.module == 'task_manager'
            names.update(
                f'{node.module}.{alias.name}' if is_root else node.module for alias in node.names
            )
    return {name for name in names if name.split('.')[0] == 'task_manager'}


def _on_edge(module: str, edge: tuple[str, ...]) -> bool:
    return any(module == allowed or module.startswith(f'{allowed}.') for allowed in edge)


def test_the_gateways_import_only_the_public_surface_of_task_manager() -> None:
    off_edge: list[str] = []
    checked = 0
    for package in GATEWAYS:
        for path in sorted((REPO / package / package).rglob('*.py')):
            edge = (*EDGE, TESTING) if path.stem.endswith('testing') else EDGE
            for module in sorted(_imported(path)):
                checked += 1
                if not _on_edge(module, edge):
                    off_edge.append(f'{path.relative_to(REPO)}: {module}')
    assert checked > 50, 'too few imports found to be read right'
    assert off_edge == [], f'gateways import past the edge (task_manager/gateway/): {off_edge}'


def test_the_contract_that_keeps_the_gateways_off_the_node_allows_no_indirect_import() -> None:
    contracts = configparser.ConfigParser()
    contracts.read(REPO / '.importlinter')
    contract = contracts['importlinter:contract:gateways-are-clients']

    assert contract.get('allow_indirect_imports', 'False') == 'False'
    assert set(GATEWAYS) <= set(contract['source_modules'].split())
    assert contract['forbidden_modules'].split() == ['task_manager.ros']
