"""The external surrogate beside the platform: a 1-DoF linear stage in the run's Diagram and on
its clock (`stage`, with `axis` the scenario's section), the external signal it follows, from a
recorded pair (`pairs`) or from a library motion through a correlation model (`correlation`), and
the figures that judge the pair (`sync_figures`: relative latency, lead, hysteresis, correlation,
drift; `report`)."""
