"""Every command the README and docs/ show is one their tools accept, where it is now.

Quick and static (no DDS): a `taskctl` line parses with taskctl's own parser (verbs, options
and their types), `make` names a target and variables of the Makefile, a program is one of the
workspace's console scripts, the files named exist, and a Python snippet compiles, its imports
resolve, and the object of its `with X(...) as name` has every attribute the snippet uses on
`name`. Running them against a robot is the work of task_manager_demo/test/test_examples.py
and the verbs' own tests.
"""

import ast
import importlib
import importlib.util
import inspect
import re
import shlex
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import typer

REPO = Path(__file__).resolve().parents[4]
DOCS = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]
FENCE = re.compile(r'^```(\w*)\n(.*?)^```', re.MULTILINE | re.DOTALL)
# Files of the repository a command names (a mission, a parameters file, a script).
REPO_FILE = re.compile(r'^(examples|task_manager\w*|docs)/\S+\.(ya?ml|json|py)$')
# Commands that need a full ROS 2 install, a running gateway or another machine: shown, not
# checked here. Any other program must be checked below.
NOT_CHECKED = {'ros2', 'colcon', 'cd', 'git', 'source', 'curl'}


@dataclass(frozen=True)
class Snippet:
    where: str  # file:line of the block's first line
    language: str
    text: str


def snippets() -> Iterator[Snippet]:
    for path in DOCS:
        text = path.read_text()
        for match in FENCE.finditer(text):
            line = text.count('\n', 0, match.start()) + 2
            yield Snippet(f'{path.relative_to(REPO)}:{line}', match.group(1), match.group(2))


def command_lines(snippet: Snippet) -> Iterator[str]:
    """The commands of a shell block: every line of `bash`, the `$ ` lines of `console`, and
    the `.venv/bin/` lines of a block of output (make run's banner); continuations joined."""
    lines = iter(snippet.text.splitlines())
    for line in lines:
        if snippet.language == 'bash':
            command = line.strip()
        elif line.startswith('$ '):
            command = line[2:].strip()
        elif snippet.language == '' and line.strip().startswith('.venv/bin/'):
            command = line.strip()
        else:
            continue
        while command.endswith('\\'):
            command = command[:-1] + next(lines).strip()
        if command and not command.startswith('#'):
            yield command


def console_scripts() -> set[str]:
    scripts: set[str] = set()
    for pyproject in REPO.glob('*/pyproject.toml'):
        with pyproject.open('rb') as file:
            scripts |= set(tomllib.load(file).get('project', {}).get('scripts', {}))
    return scripts


@pytest.fixture(scope='module')
def taskctl() -> typer.Typer:
    """taskctl's application."""
    app: typer.Typer = importlib.import_module('task_manager.cli.main').app
    return app


def parse_taskctl(app: typer.Typer, argv: list[str]) -> None:
    """Parse as taskctl would, down to the verb; raises its usage error."""
    command: Any = typer.main.get_command(app)
    context = command.make_context('taskctl', list(argv))
    while hasattr(command, 'resolve_command'):  # a group: its options parsed, then the verb
        rest = argv[len(argv) - len(context.args) - 1 :]
        name, command, verb_argv = command.resolve_command(context, rest)
        context = command.make_context(name, verb_argv, parent=context)
        argv = verb_argv


def check_command(taskctl: typer.Typer, where: str, line: str) -> None:
    argv = shlex.split(line, comments=True)
    program = argv[0].removeprefix('.venv/bin/')
    for argument in argv[1:]:
        if REPO_FILE.match(argument):
            assert (REPO / argument).is_file(), f'{where}: {line}: no file {argument}'
    if program in NOT_CHECKED:
        return
    if program == 'make':
        makefile = (REPO / 'Makefile').read_text()
        for argument in argv[1:]:
            variable, is_setting, _ = argument.partition('=')
            pattern = rf'^{variable} \?=' if is_setting else rf'^{argument}:'
            assert re.search(pattern, makefile, re.MULTILINE), f'{where}: {line}: {argument}'
    elif program == 'python' and argv[1] == '-m':
        # run from the repository's root, where `python -m` also finds its folders (bench)
        top = argv[2].split('.')[0]
        found = (REPO / top).is_dir() or importlib.util.find_spec(argv[2]) is not None
        assert found, f'{where}: {line}: no module {argv[2]}'
    elif program == 'python':
        assert REPO_FILE.match(argv[1]), f'{where}: {line}: not a script of the repository'
        source = (REPO / argv[1]).read_text()
        for option in (a.split('=')[0] for a in argv[2:] if a.startswith('--')):
            assert f"'{option}'" in source, f'{where}: {line}: {argv[1]} takes no {option}'
    elif program == 'taskctl':
        try:
            parse_taskctl(taskctl, argv[1:])
        except Exception as error:  # taskctl's usage error: the command as shown is refused
            pytest.fail(f'{where}: {line}: {type(error).__name__}: {error}')
    else:
        assert program in console_scripts(), f'{where}: {line}: unknown program {program}'


SHELL = [s for s in snippets() if s.language in ('bash', 'console', '')]
PYTHON = [s for s in snippets() if s.language == 'python']


def test_the_docs_show_commands_and_snippets() -> None:
    commands = [line for snippet in SHELL for line in command_lines(snippet)]

    assert any(line.startswith('.venv/bin/taskctl') for line in commands)
    assert len(PYTHON) >= 3  # the client, a schedule, the FleetClient


@pytest.mark.parametrize('snippet', SHELL, ids=[s.where for s in SHELL])
def test_shell_commands_are_accepted(taskctl: typer.Typer, snippet: Snippet) -> None:
    for line in command_lines(snippet):
        check_command(taskctl, snippet.where, line)


def has_attribute(owner: object, name: str) -> bool:
    """A class attribute, or one its code sets on `self`."""
    if hasattr(owner, name):
        return True
    return inspect.isclass(owner) and bool(
        re.search(rf'self\.{name}\b\s*[:=]', inspect.getsource(owner))
    )


@pytest.mark.parametrize('snippet', PYTHON, ids=[s.where for s in PYTHON])
def test_python_snippets_compile_and_use_what_exists(snippet: Snippet) -> None:
    tree = ast.parse(snippet.text, snippet.where)
    compile(tree, snippet.where, 'exec')
    imported: dict[str, object] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            module = importlib.import_module(node.module)
            for alias in node.names:
                assert hasattr(module, alias.name), f'{snippet.where}: {alias.name}'
                imported[alias.asname or alias.name] = getattr(module, alias.name)
    used_as: dict[str, object] = {}  # key: the name of `with X(...) as name`, value: X
    for node in ast.walk(tree):
        if isinstance(node, ast.With):
            for item in node.items:
                call, target = item.context_expr, item.optional_vars
                if (
                    isinstance(call, ast.Call)
                    and isinstance(call.func, ast.Name)
                    and isinstance(target, ast.Name)
                    and call.func.id in imported
                ):
                    used_as[target.id] = imported[call.func.id]
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in used_as
        ):
            owner = used_as[node.value.id]
            assert has_attribute(owner, node.attr), f'{snippet.where}: {owner} has no {node.attr}'


LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lowercase, punctuation dropped, spaces to '-'."""
    return re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')


def outside_code(text: str) -> str:
    return FENCE.sub(lambda match: '\n' * match.group(0).count('\n'), text)


def anchors(path: Path) -> set[str]:
    seen: dict[str, int] = {}  # key: an anchor, value: how many headings had it before
    found = set()
    for heading in re.findall(r'^#{1,6} (.*)$', outside_code(path.read_text()), re.MULTILINE):
        base = slug(heading)
        found.add(f'{base}-{seen[base]}' if base in seen else base)
        seen[base] = seen.get(base, 0) + 1
    return found


@pytest.mark.parametrize('page', DOCS, ids=[str(p.relative_to(REPO)) for p in DOCS])
def test_relative_links_and_anchors_resolve(page: Path) -> None:
    broken = []
    for target in LINK.findall(outside_code(page.read_text())):
        if re.match(r'[a-z]+:', target):
            continue  # https:, mailto:
        file_part, _, anchor = target.partition('#')
        destination = (page.parent / file_part).resolve() if file_part else page
        if not destination.exists():
            broken.append(f'{target}: no such file')
        elif anchor and anchor not in anchors(destination):
            broken.append(f'{target}: no heading #{anchor}')

    assert not broken, broken
