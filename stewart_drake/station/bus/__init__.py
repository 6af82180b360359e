"""Real servos: the DYNAMIXEL Protocol 2.0 subset the robot needs (:mod:`.protocol`), a driver
through the vendor's ``dynamixel_sdk`` (:mod:`.driver`, extra ``robot``) and a bus emulator on a
pseudo-terminal with a motion model behind it (:mod:`.emulator`). docs/hardware_bus.md."""
