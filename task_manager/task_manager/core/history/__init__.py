"""The durable task history: the SQLite store, where its file lives, and statistics over ended
tasks."""
