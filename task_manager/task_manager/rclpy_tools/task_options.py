"""TaskOptions (StartTask's goal and ScheduleTask's request) to and from RequestOptions."""

from task_manager_msgs.msg import TaskOptions

from task_manager.core.admission.options import OnConflict, RequestOptions, parse_on_conflict


def options_of_message(message: TaskOptions) -> RequestOptions:
    """The options of a message; zero and empty fields take the declaration's values."""
    on_conflict: OnConflict | None = None
    error = ''
    if message.on_conflict.strip():
        try:
            on_conflict = parse_on_conflict(message.on_conflict)
        except ValueError as problem:
            error = str(problem)
    return RequestOptions(
        priority=message.priority if message.has_priority else None,
        on_conflict=on_conflict,
        timeout_sec=message.timeout_sec or None,
        queue_timeout_sec=message.queue_timeout_sec or None,
        feedback_timeout_sec=message.feedback_timeout_sec or None,
        error=error,
    )


def task_options_msg(options: RequestOptions) -> TaskOptions:
    return TaskOptions(
        has_priority=options.priority is not None,
        priority=options.priority or 0,
        on_conflict=str(options.on_conflict or ''),
        timeout_sec=float(options.timeout_sec or 0.0),
        queue_timeout_sec=float(options.queue_timeout_sec or 0.0),
        feedback_timeout_sec=float(options.feedback_timeout_sec or 0.0),
    )
