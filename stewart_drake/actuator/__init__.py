"""A servo identified on its bench: its logs (:mod:`.bench_log`), the bench simulated
(:mod:`.bench`), the identification of its drive and friction (:mod:`.identify`), the model's file
(:mod:`.model_file`) and the ``servo`` command (:mod:`.command`)."""
