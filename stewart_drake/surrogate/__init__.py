"""An external surrogate beside the platform: the internal target's motion and the chest's
surrogate judged together on one clock, with their relative latency (:mod:`.relative_latency`)."""
