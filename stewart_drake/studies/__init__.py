"""Studies built on closed-loop runs: experiments and metrics, the tuner's data collection and
training (torch), the evaluation grid, the workspace sweeps, and the runners that execute them."""
