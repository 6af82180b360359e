"""The robot driven live: the controller Diagram on six servos with its safety sequence
(:mod:`.session`, ``stewart-drake robot``), teleoperation in Meshcat (``teleop``) and the bus
emulator that rehearses both."""
