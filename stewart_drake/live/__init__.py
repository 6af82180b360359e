"""The robot driven live: the controller Diagram on six servos with its safety sequence
(:mod:`.session`, ``stewart-drake robot``; the pose read with the torque off, :mod:`.measure`;
our watchdog, :mod:`.watchdog`), teleoperation in Meshcat (``teleop``), the robot's plant behind
the bus emulator of :mod:`stewart_drake.station.bus.emulator`, which rehearses both
(:mod:`.plant_backend`, in a process of its own :mod:`.emulator_process`), and a calibration
rehearsed over it (:mod:`.calibration_rehearsal`). A run's measured motion is judged by
``verify``, in :mod:`stewart_drake.verification`, which never drives the robot."""
