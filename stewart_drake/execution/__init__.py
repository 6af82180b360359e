"""How a study's independent jobs run (this process, local processes: :mod:`.runners`; Ray,
Dask: :mod:`.clusters`) and how their results are kept as they arrive and resumed
(:mod:`.store`)."""
