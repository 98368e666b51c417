"""taskctl active [--watch] and taskctl results [--follow]."""

import json
from collections.abc import Iterator, Sequence
from dataclasses import replace
from datetime import UTC, datetime
from typing import TypeAlias

import typer
from rich.live import Live
from rich.table import Table
from rich.text import Text

from task_manager import (
    ActiveTaskInfo,
    EventsLost,
    TaskEvent,
    TaskEventKind,
    TaskManagerClient,
    TaskResult,
    TaskState,
    TaskStatus,
)
from task_manager.cli.common import connected, duration_text, output, time_text
from task_manager.cli.records import active_data, json_line, prompt_of, result_data
from task_manager.cli.verbs.start import status_text
from task_manager.core.names import GET_TASK_RESULTS_SERVICE, GET_TASK_STATES_SERVICE

ActiveRow: TypeAlias = ActiveTaskInfo | TaskState
ACTIVE_JSON_HELP = (
    'One JSON object per task and line; with --watch, one JSON list of them per line and change'
)


STATUS_STYLES = {TaskStatus.PAUSED: 'yellow', TaskStatus.QUEUED: 'cyan'}


def active_table(tasks: Sequence[ActiveRow]) -> Table:
    """The active tasks; `running for` needs their stamps (TaskState rows), and stops while
    a task is PAUSED; a QUEUED task shows its place in the queue (`QUEUED #2`); a waiting
    system/confirm its prompt (a column shown while one waits)."""
    table = Table(title=f'active tasks ({len(tasks)})')
    prompts = [prompt_of(task) for task in tasks]
    waiting = ('waiting for an answer',) if any(prompts) else ()
    for column in ('id', 'task', 'status', 'source', 'running for', 'priority', *waiting):
        table.add_column(column)
    for task, prompt in zip(tasks, prompts, strict=True):
        state = task if isinstance(task, TaskState) else None
        elapsed = state.elapsed() if state is not None else None
        position = state.queue_position if state is not None else 0
        table.add_row(
            task.task_id,
            task.task_name,
            Text(status_text(task.status, position), style=STATUS_STYLES.get(task.status, '')),
            task.source,
            duration_text(elapsed) if elapsed is not None else '',
            str(state.priority) if state is not None else '',
            *([Text(prompt, style='bold magenta')] if waiting else []),
        )
    return table


class StampedActiveTasks:
    """The active tasks with their stamps, kept up to date from /task_manager/active_tasks.

    First every active task from /task_manager/get_task_states (the latest list on the
    topic may reach a new subscriber after older ones); then the topic's lists, with the
    stamps of each task asked for once, and again when its status changes (a start, a pause
    or resume, its end), and at each change while it is QUEUED (its place moves as others
    leave the queue or change priority).
    """

    def __init__(self, client: TaskManagerClient) -> None:
        self._client = client
        self.rows: list[ActiveRow] = list(client.task_states())
        # key: task id, value: its state when last asked
        self._states: dict[str, TaskState] = {s.task_id: s for s in self.rows}

    def update(self, tasks: list[ActiveTaskInfo]) -> list[ActiveRow]:
        stale = [
            t.task_id
            for t in tasks
            if t.task_id not in self._states
            or t.status is not self._states[t.task_id].status
            or t.status is TaskStatus.QUEUED
        ]
        if stale:
            self._states.update((s.task_id, s) for s in self._client.task_states(stale))
        known = {t.task_id for t in tasks}
        self._states = {i: s for i, s in self._states.items() if i in known}
        self.rows = [
            replace(self._states[t.task_id], status=t.status) if t.task_id in self._states else t
            for t in tasks
        ]
        return self.rows


def active(
    ctx: typer.Context,
    watch: bool = typer.Option(False, '--watch', help='Keep the table up to date until Ctrl-C'),
    as_json: bool = typer.Option(False, '--json', help=ACTIVE_JSON_HELP),
) -> None:
    """Show the tasks in progress."""
    try:
        with connected(ctx, services=[GET_TASK_STATES_SERVICE]) as client:
            # followed before the states are read: a change between the two is not lost
            updates = client.active_task_updates() if watch else iter(())
            tasks = StampedActiveTasks(client)
            if as_json:
                print_active_json(tasks.rows, as_list=watch)
                for update in updates:
                    print_active_json(tasks.update(update), as_list=True)
            elif not watch:
                output.print(active_table(tasks.rows))
            elif output.is_terminal:  # redrawn as time passes, too
                with Live(get_renderable=lambda: active_table(tasks.rows), console=output) as live:
                    for update in updates:
                        tasks.update(update)
                        live.refresh()
            else:  # a pipe: one table per change, as it happens
                output.print(active_table(tasks.rows))
                for update in updates:
                    output.print(active_table(tasks.update(update)))
                    output.file.flush()
    except KeyboardInterrupt:  # how watching ends, wherever it is
        pass


def print_active_json(rows: Sequence[ActiveRow], as_list: bool) -> None:
    """The active tasks as JSON: one object per line, or (`as_list`) one list of them."""
    now = datetime.now(UTC)
    data = [active_data(row, now) for row in rows]
    for line in [json_line(data)] if as_list else [json_line(item) for item in data]:
        print(line, flush=True)


def result_line(result: TaskResult, as_json: bool) -> str:
    duration = result.duration
    if as_json:
        return json_line(result_data(result))
    error = f' ({result.error_code})' if result.error_code else ''
    when = ''
    if result.ended_at is not None:
        took = f' after {duration_text(duration)}' if duration is not None else ', never started'
        when = f'  ended {time_text(result.ended_at)}{took}'
    return (
        f'{result.status}{error}  {result.task_name}  {result.task_id}  '
        f'from {result.source!r}{when}  {json.dumps(result.result, ensure_ascii=False)}'
    )


ABOVE_MAX = 1000
"""Results shown above `ShownResults.floor` at most: more, and the numbers below them are taken
for gone (numbers the Task Manager gave without an event: those it closed at a restart)."""


class ShownResults:
    """The history's numbers (`sequence`) of the results shown: `floor`, up to which each one
    was shown or ended before the following began, and those shown above it (results shown
    out of turn, their events having gone missing)."""

    def __init__(self) -> None:
        self.floor: int | None = None
        self.above: set[int] = set()

    def first_time(self, sequence: int) -> bool:
        """Whether the result numbered `sequence` is new here; noted as shown. (0: a result
        without a number, always new.)"""
        if sequence <= 0:
            return True
        if self.floor is None:
            self.floor = sequence
            return True
        if sequence <= self.floor or sequence in self.above:
            return False
        self.above.add(sequence)
        while self.floor + 1 in self.above:
            self.floor += 1
            self.above.discard(self.floor)
        if len(self.above) > ABOVE_MAX:
            self.filled()
        return True

    def filled(self) -> None:
        """The history was read after `floor`: what it no longer has is gone for good."""
        if self.above:
            self.floor = max(self.above)
            self.above.clear()


def new_results(client: TaskManagerClient) -> Iterator[TaskResult]:
    """Results as tasks end, from this call on: from ENDED events (with stamps) when they
    reach us, else plain."""
    if not client.events_connected:
        plain: Iterator[TaskResult] = client.results()
        return plain
    return _results_of_events(client)


def _results_of_events(client: TaskManagerClient) -> Iterator[TaskResult]:
    """The results the ENDED events carry, from this call on (not from the first `next()`),
    each once; when events went missing (taskctl fell more than its reader keeps behind the
    Task Manager), the results among them are read from the history (by number, after the
    last one shown in turn), so that none is skipped."""
    return _shown_once(client, client.task_events(losses=True))


def _shown_once(
    client: TaskManagerClient, arrived: Iterator[TaskEvent | EventsLost]
) -> Iterator[TaskResult]:
    shown = ShownResults()
    for item in arrived:
        if isinstance(item, EventsLost):
            yield from _missed_results(client, shown)
        elif item.kind is TaskEventKind.ENDED and shown.first_time(item.task.sequence):
            yield item.task.to_result()


def _missed_results(client: TaskManagerClient, shown: ShownResults) -> Iterator[TaskResult]:
    """The history's results after `shown.floor` not shown yet, oldest first, to its newest
    (those whose events are still on the way are then not shown again). Before a first result
    was shown there is no place to start from: the client's warning says events were lost."""
    if shown.floor is None:
        return
    for state in client.ended_after(shown.floor):
        if shown.first_time(state.sequence):
            yield state.to_result()
    shown.filled()


def results(
    ctx: typer.Context,
    follow: bool = typer.Option(
        False, '--follow', '-f', help='Then print new results as they come'
    ),
    limit: int = typer.Option(
        20, '--limit', min=0, help='At most this many kept results first, the latest (0: all)'
    ),
    last: int | None = typer.Option(None, '--last', min=0, hidden=True),  # --limit's old name
    as_json: bool = typer.Option(False, '--json', help='One JSON object per result and line'),
) -> None:
    """Print the latest task results the Task Manager kept, oldest first: when each ended."""
    try:
        with connected(ctx, events=follow, services=[GET_TASK_RESULTS_SERVICE]) as client:
            # followed before the kept results are read: a task that ends between the two is
            # not lost (and shown once: it may be in both)
            following = new_results(client) if follow else iter(())
            kept = client.recent_results(limit if last is None else last)
            for result in kept:
                print(result_line(result, as_json), flush=True)
            shown = {(result.task_id, result.ended_at) for result in kept}
            for result in following:
                if (result.task_id, result.ended_at) not in shown:
                    print(result_line(result, as_json), flush=True)
    except KeyboardInterrupt:  # how following ends, wherever it is
        pass
