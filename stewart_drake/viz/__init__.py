"""Pictures of runs and of the Diagram: Meshcat replays as standalone HTML, Graphviz pictures of
the Diagram. A feature the others draw with."""
