"""The paper's experiment: ``stewart-drake run`` prints a run's figures and draws the paper's
Fig. 7 (:mod:`.run_report`)."""
