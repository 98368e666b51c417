"""ResultOutbox: which results the broker has, and what a restart sends again (no ROS)."""

from pathlib import Path

from task_manager_mqtt.outbox import ResultOutbox


def send(outbox: ResultOutbox, sequence: int, message_id: int) -> None:
    outbox.before_send()
    outbox.mark_sent(sequence, message_id)


def test_acknowledged_advances_only_over_an_unbroken_run(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    for sequence in (1, 2, 3):
        send(outbox, sequence, message_id=100 + sequence)
    outbox.on_ack(102)
    assert (outbox.sent, outbox.acked) == (3, 0)  # 1 still unacknowledged
    outbox.on_ack(101)
    assert outbox.acked == 2
    outbox.on_ack(103)
    assert outbox.acked == 3
    assert ResultOutbox(tmp_path / 'acked').acked == 3  # kept on disk


def test_an_acknowledgement_before_publish_returned_counts(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    outbox.before_send()
    outbox.on_ack(7)  # the broker was quicker than publish() returning the message id
    outbox.mark_sent(1, 7)
    assert outbox.acked == 1


def test_acknowledgements_of_other_messages_are_not_taken_for_results(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    outbox.on_ack(5)  # a reply's
    send(outbox, 1, message_id=5)  # a later result with the same (reused) id
    assert outbox.acked == 0


def test_a_restart_sends_again_what_was_not_acknowledged(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    for sequence in (1, 2, 3):
        send(outbox, sequence, message_id=sequence)
    outbox.on_ack(1)
    restarted = ResultOutbox(tmp_path / 'acked')
    assert restarted.known and (restarted.acked, restarted.sent) == (1, 1)
    assert restarted.is_next(2) and not restarted.is_sent(2)


def test_a_reconnection_resends_from_the_last_acknowledged(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    for sequence in (1, 2, 3):
        send(outbox, sequence, message_id=sequence)
    outbox.on_ack(1)
    outbox.resend_unacked()
    assert outbox.sent == 1
    send(outbox, 2, message_id=12)
    outbox.on_ack(2)  # the MQTT client's own resend of the first 2 was acknowledged
    assert outbox.acked == 2
    outbox.on_ack(12)
    assert outbox.acked == 2


def test_a_first_start_begins_from_now(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'state' / 'acked')
    assert not outbox.known
    outbox.start_at(41)
    assert outbox.is_next(42) and ResultOutbox(tmp_path / 'state' / 'acked').acked == 41


def test_the_last_acknowledged_is_kept_with_its_task_id(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked')
    for sequence in (1, 2):
        outbox.before_send()
        outbox.mark_sent(sequence, 100 + sequence, f'task-{sequence}')
    outbox.on_ack(102)
    outbox.on_ack(101)
    kept = ResultOutbox(tmp_path / 'acked')
    assert (kept.acked, kept.acked_task_id) == (2, 'task-2')


def test_a_file_written_before_the_task_id_was_kept_is_read(tmp_path: Path) -> None:
    (tmp_path / 'acked').write_text('41\n')
    outbox = ResultOutbox(tmp_path / 'acked')
    assert (outbox.known, outbox.acked, outbox.acked_task_id) == (True, 41, '')


def test_acknowledgements_that_come_together_are_written_once(tmp_path: Path) -> None:
    asked: list[int] = []
    outbox = ResultOutbox(tmp_path / 'acked', lambda: asked.append(outbox.acked))
    outbox.start_at(0)
    for sequence in (1, 2, 3):
        send(outbox, sequence, message_id=sequence)
    for message_id in (1, 2, 3):
        outbox.on_ack(message_id)
    assert (outbox.acked, asked) == (3, [1])  # one write asked for, by the first
    assert ResultOutbox(tmp_path / 'acked').acked == 0  # not written yet
    outbox.write_acked()
    assert ResultOutbox(tmp_path / 'acked').acked == 3
    send(outbox, 4, message_id=4)
    outbox.on_ack(4)
    assert asked == [1, 4]  # asked again once the last was written
    outbox.write_acked()
    restarted = ResultOutbox(tmp_path / 'acked')
    assert (restarted.acked, restarted.sent) == (4, 4)


def test_an_acknowledged_position_already_written_is_not_written_again(tmp_path: Path) -> None:
    outbox = ResultOutbox(tmp_path / 'acked', lambda: None)
    outbox.start_at(5, 'five')
    (tmp_path / 'acked').unlink()
    outbox.write_acked()  # nothing moved since start_at wrote it
    assert not (tmp_path / 'acked').exists()
