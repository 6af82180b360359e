"""How a study's independent jobs run (this process, local processes, Ray, Dask:
:mod:`.runners`) and how their results are kept as they arrive and resumed (:mod:`.store`)."""
