"""The tuners of the LQI's weights trained and tested: the paper's nine collection runs
(``collect``), the ANN's training (``train``, torch), and the tuner study: does tuning online
beat the best fixed ratio (:mod:`.tuner_study`)."""
