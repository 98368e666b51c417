"""docs/architecture.md is a true map: every module and folder it names exists, and every arrow
it forbids is a contract that `lint-imports` (run by `make lint` and `make test`) checks."""

import configparser
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[4]
MAP = REPO / 'docs' / 'architecture.md'
SKIPPED_FOLDERS = {'.venv', 'build', 'install', 'log', 'node_modules', '__pycache__', '.git'}
# A module or folder named in backquotes: `ros/running/dispatcher.py`, `fleet.py`, `static/`.
NAMED_PATH = re.compile(r'`([A-Za-z_][\w./-]*(?:\.py|/))`')

# What the map says may not be imported (its words, white space folded), and the contract of
# .importlinter that holds it.
CLAIMS_AND_CONTRACTS = [
    ('`core/` decides, in plain Python (no rclpy)', 'core'),
    ('The client imports nothing of `ros/`', 'client'),
    ('They reach the node only through `TaskManagerClient`', 'gateways-are-clients'),
    ('is imported only by tests', 'testing'),
    ('it loads no rclpy and reaches the robots only through the broker', 'console'),
    ('which `python -m task_manager.protocol` writes', 'protocol'),
    ('reaches the node through TaskManagerClient too', 'vda5050'),
    ('Within `ros/running/` arrows point one way', 'running'),
]


def _repository_paths() -> list[str]:
    """Every file and folder of the repository, relative, with folders ending in '/'."""
    found: list[str] = []
    stack = [REPO]
    while stack:
        folder = stack.pop()
        for entry in folder.iterdir():
            if entry.name in SKIPPED_FOLDERS or entry.name.endswith('.egg-info'):
                continue
            relative = entry.relative_to(REPO).as_posix()
            if entry.is_dir():
                found.append(relative + '/')
                stack.append(entry)
            else:
                found.append(relative)
    return found


def _exists(named: str, paths: list[str]) -> bool:
    """A named module or folder is some path of the repository, or its end after a '/'."""
    return any(path == named or path.endswith('/' + named) for path in paths)


def test_every_module_and_folder_the_map_names_exists() -> None:
    named = sorted(set(NAMED_PATH.findall(MAP.read_text())))
    assert len(named) > 50, f'the map names too few modules to be read right: {named}'
    paths = _repository_paths()
    missing = [name for name in named if not _exists(name, paths)]
    assert missing == [], f'docs/architecture.md names modules that do not exist: {missing}'


@pytest.mark.parametrize(('claim', 'contract'), CLAIMS_AND_CONTRACTS)
def test_every_forbidden_arrow_of_the_map_is_a_contract(claim: str, contract: str) -> None:
    words = ' '.join(MAP.read_text().split())
    assert claim in words, f'the map no longer says {claim!r}: update this table'
    contracts = configparser.ConfigParser()
    contracts.read(REPO / '.importlinter')
    assert contracts.has_section(f'importlinter:contract:{contract}'), (
        f'the map says {claim!r}, and no contract {contract!r} in .importlinter checks it'
    )
