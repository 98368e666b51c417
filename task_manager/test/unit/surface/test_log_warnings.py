"""Python's warnings in the node's log: a done callback that raised, which rclpy runs in place
for a future without an executor (the node's requests), is an error line each time it
happens; another warning is a warning line."""

import warnings

from rclpy.task import Future

from task_manager.rclpy_tools.log import log_warnings


class Lines:
    """Stands in for a logger: the lines it was given, with their level."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def error(self, text: str) -> None:
        self.lines.append(('error', text))

    def warning(self, text: str) -> None:
        self.lines.append(('warning', text))


def _fail(_: Future[int]) -> None:
    raise ValueError('a bug in a callback')


def test_each_done_callback_that_raised_is_an_error_line_and_another_warning_a_warning() -> None:
    log = Lines()
    with warnings.catch_warnings():  # what log_warnings changes is put back after
        log_warnings(log)
        for _ in range(2):
            future: Future[int] = Future()
            future.add_done_callback(_fail)
            future.set_result(1)
        warnings.warn('something else', DeprecationWarning, stacklevel=1)

    assert [level for level, _ in log.lines] == ['error', 'error', 'warning']
    assert 'a bug in a callback' in log.lines[0][1]
    assert log.lines[2][1].startswith('DeprecationWarning: something else (')
