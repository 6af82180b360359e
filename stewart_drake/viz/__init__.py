"""Pictures of runs and of the Diagram: Meshcat replays as standalone HTML (:mod:`.visualize`),
Graphviz pictures of the Diagram (:mod:`.diagrams`). A feature the others draw with."""
