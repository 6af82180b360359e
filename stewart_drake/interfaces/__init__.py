"""What users touch: the ``stewart-drake`` command and the pictures (Meshcat replays, Diagram
graphs). The top layer: it imports every other, nothing imports it."""
