"""The robot driven live: the controller Diagram on six servos with its safety sequence
(:mod:`.session`, ``stewart-drake robot``; the pose read with the torque off, :mod:`.measure`;
our watchdog, :mod:`.watchdog`), teleoperation in Meshcat (``teleop``), the robot's plant behind the
bus emulator of :mod:`stewart_drake.station.bus.emulator`, which rehearses both
(:mod:`.plant_backend`, in a process of its own :mod:`.emulator_process`), a calibration
rehearsed over it (:mod:`.calibration_rehearsal`), and a run's measured motion judged against
its reference (``verify``, :mod:`.verify_command`), alone or with its surrogate on one clock
(``verify --surrogate``: :mod:`.pair_judgement`, :mod:`.pair_command`, :mod:`.pair_report`)."""
