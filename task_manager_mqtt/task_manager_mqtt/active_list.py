"""The bridge's list of active tasks and its `active_tasks` document, whose JSON text is made
from each task's own text, kept from when that task last changed.

The bridge publishes the list at each change (several changes in one message when they come
together). Encoding the whole list each time made a burst quadratic: 500 tasks started at once
were some hundreds of lists of up to 500 tasks, about a quarter of the bridge's CPU. Now a
change encodes the one task, and a list is its kept texts joined, the same bytes as
`compact_json` of the whole document.
"""

from collections.abc import Iterable
from typing import Any

from task_manager.core.text.json_text import compact_json

Document = dict[str, Any]


class ActiveList:
    """Task id -> the Task document of each active task, and its text."""

    def __init__(self) -> None:
        self._tasks: dict[str, tuple[Document, str]] = {}

    def __len__(self) -> int:
        return len(self._tasks)

    def put(self, task_id: str, task: Document) -> None:
        """Add the task, or change it."""
        self._tasks[task_id] = (task, compact_json(task))

    def discard(self, task_id: str) -> None:
        """Take the task out, if it is in."""
        self._tasks.pop(task_id, None)

    def replace(self, tasks: Iterable[Document]) -> None:
        """The list is these tasks (each with its `task_id`), in this order."""
        self._tasks = {}
        for task in tasks:
            self.put(task['task_id'], task)

    def document(self, timestamp: str | None) -> Document:
        """The `active_tasks` document: `timestamp` and the tasks, oldest first."""
        return {'timestamp': timestamp, 'tasks': [task for task, _ in self._tasks.values()]}

    def payload(self, timestamp: str | None) -> bytes:
        """`compact_json(self.document(timestamp))`, encoded, from the kept texts."""
        empty = compact_json({'timestamp': timestamp, 'tasks': []})
        head = empty[: -len(']}')]
        return f'{head}{",".join(text for _, text in self._tasks.values())}]}}'.encode()
