"""The robot driven live: the controller Diagram on six servos with its safety sequence
(:mod:`.session`, ``stewart-drake robot``; the pose read with the torque off, :mod:`.measure`;
our watchdog, :mod:`.watchdog`), teleoperation in Meshcat (``teleop``), the bus emulator that
rehearses both, and a calibration rehearsed over it (:mod:`.calibration_rehearsal`)."""
