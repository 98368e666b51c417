"""Fixtures of the unit tests."""

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

import task_manager.client

PACKAGE = Path(task_manager.client.__file__).parents[1]  # client/ is a package of it


@pytest.fixture(scope='module')
def package_root() -> Iterator[ModuleType]:
    """The package root with its public API, as `import task_manager` in the tests' modules.

    The root conftest puts the repository on sys.path, where the colcon folder `task_manager/`
    passes for a namespace package of that name and hides the package's `__init__.py` (its
    submodules are still found). Code that imports the root's public API, such as taskctl,
    is imported through this fixture.
    """
    with pytest.MonkeyPatch.context() as patch:
        if getattr(sys.modules.get('task_manager'), '__file__', None) is None:
            spec = importlib.util.spec_from_file_location(
                'task_manager', PACKAGE / '__init__.py', submodule_search_locations=[str(PACKAGE)]
            )
            assert spec is not None and spec.loader is not None
            root = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(root)
            patch.setitem(sys.modules, 'task_manager', root)
        yield sys.modules['task_manager']
