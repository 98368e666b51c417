"""The history as the doors answer it: a page of at most so many bytes (`page.py`), JSON or
CSV (`csv_export.py`). Shared with the fleet console (no rclpy here)."""
