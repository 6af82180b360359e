"""A robot designed for a task: its design variables, the task as a file, the search, the
confirmation in closed loop and the report (``stewart-drake design``)."""
