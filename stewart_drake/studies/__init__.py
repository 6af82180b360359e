"""Studies built on closed-loop runs: experiments and metrics, the tuner's data collection and
training (torch), the evaluation grid, the workspace sweeps; their jobs run and are kept by
:mod:`stewart_drake.execution`."""
