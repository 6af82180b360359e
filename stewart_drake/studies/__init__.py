"""Studies built on closed-loop runs: experiments and metrics, the tuner's data collection and
training (torch), the evaluation grid, the workspace sweeps, the runners that execute them
(runners) and the folders that keep their results as they arrive (store)."""
