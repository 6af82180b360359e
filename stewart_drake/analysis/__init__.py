"""The robot and its loop analysed without the paper's manoeuvre: margins, sensitivity and
bandwidth of the linearised loop (:mod:`.loop_analysis`, ``stewart-drake analyze``), the
workspace of states and torques (``workspace``), every margin of a reference without simulating
it (:mod:`.feasibility`, ``check``), and the plant's accuracy against MuJoCo (:mod:`.accuracy`)."""
