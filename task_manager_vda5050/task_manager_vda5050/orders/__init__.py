"""What the vehicle is told to do: an order checked and planned as missions, in plain Python
(`plan.py`), orders carried out through the Task Manager and their progress (`running.py`), and
the instant actions (`instant_actions.py`)."""
