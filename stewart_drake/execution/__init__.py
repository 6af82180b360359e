"""Job execution and persistence: the runners that execute independent jobs (runners) and the
folders that keep their results as they arrive (store)."""
