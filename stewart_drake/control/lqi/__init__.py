"""The LQI of paper section III, re-scheduled online: its options as a scenario's choice
(:mod:`.driver`), the gain design in numpy and Drake (:mod:`.gain`), the Drake system
(:mod:`.controller`), and its compiled code, the control period (:mod:`.step`) and the gain's
re-schedule (:mod:`.reschedule`), loaded together by :mod:`.kernels` over the names of
:mod:`.layout`."""
