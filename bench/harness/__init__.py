"""The bench's machinery: its client, the processes it starts, statistics and the report."""
