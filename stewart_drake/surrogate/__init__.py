"""An external surrogate beside the platform: the internal target's motion and the chest's
surrogate judged together on one clock, with their relative latency: judged
(:mod:`.pair_judgement`; the causes of a FAIL, :mod:`.pair_causes`), read and run as ``verify
--surrogate`` (:mod:`.pair_command`) and written (:mod:`.pair_report`)."""
