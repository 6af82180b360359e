"""Calibration of the robot as built from a tracker's measurements, on the per-leg model and the
tolerances of :mod:`stewart_drake.robot` (`legs`, `tolerances`): the emulated tracker and
encoders (`tracker`), the identification with the tolerances as its prior, its outliers and
held-out check (`identify`), the choice of the poses to measure and the path through them
(`poses`), the files it reads and writes (`files`), the join of a session's encoder log and
tracker file into measurements (`join`), the registration of the tracker's frames
(`registration`) and its file, REG.yaml (`registration_file`), what an estimate is worth
(`validation`), the rehearsal on an emulated robot and its study (`rehearsal`), the error budget
of a real laboratory (`budget`) and what the command prints (`report`); the ``calibrate``
command is :mod:`stewart_drake.live.calibrate_command` (its rehearsal over the bus drives the
robot live).
docs/calibration.md."""
