"""TaskResult, the Python client's view of how a task ended, built from real messages."""

from task_manager_msgs.action import ExecuteTask
from task_manager_msgs.msg import TaskDoneResult

from task_manager.client import TaskResult
from task_manager.core.status import ErrorCode, TaskStatus


def test_a_refusal_exposes_its_reason() -> None:
    message = TaskDoneResult(
        task_id='t1',
        task_name='nav',
        task_status='ERROR',
        source='CLOUD',
        error_code='unknown_task',
        task_result='{"error": "unknown task \'nav\'; declared tasks: dock"}',
    )

    result = TaskResult.from_message(message)

    assert (result.status, result.error_code) == (TaskStatus.ERROR, ErrorCode.UNKNOWN_TASK)
    assert result.error_message == "unknown task 'nav'; declared tasks: dock"
    assert result.source == 'CLOUD'


def test_a_task_result_without_an_error_string_has_no_message() -> None:
    done = ExecuteTask.Result(task_id='t2', task_status='DONE', task_result='{"error": 3}')
    empty = ExecuteTask.Result(task_id='t3', task_status='ERROR', task_result='')

    assert TaskResult.from_message(done, 'count', 'CLI').error_message == ''
    assert TaskResult.from_message(empty, 'count', 'CLI').error_message == ''


def test_an_execute_task_result_takes_the_name_and_source_of_its_goal() -> None:
    message = ExecuteTask.Result(task_id='t4', task_status='DONE', task_result='{}')

    result = TaskResult.from_message(message, 'dock', 'CLI')

    assert (result.task_name, result.source, result.ok) == ('dock', 'CLI', True)


def test_a_result_that_is_not_a_json_object_is_kept_raw() -> None:
    for text in ('[1, 2]', '{not json'):
        message = ExecuteTask.Result(task_id='t5', task_status='DONE', task_result=text)

        assert TaskResult.from_message(message).result == {'raw': text}
