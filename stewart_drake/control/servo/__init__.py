"""The crank servo, the controller of the robot on its servo bus: its options as a scenario's
choice (:mod:`.driver`), one crank's loop designed with Drake's DARE and pole placement
(:mod:`.design`), the Drake system (:mod:`.controller`) and its compiled control period
(:mod:`.kernels`)."""
