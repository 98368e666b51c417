"""Text a request carries and the Task Manager writes: what an id, a task name or a source may
hold and how it goes into a log line (`request_text`), and compact JSON text of results and
feedback (`json_text`)."""
