"""What the vehicle reports: its state, kept up to date from the task events (`vehicle_state.py`,
pure), made to fit the broker's limit (`fitting.py`), and its factsheet (`factsheet.py`)."""
