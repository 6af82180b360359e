"""Simulation: references, the scenario, the station (plant + hardware), the closed-loop Diagram
and its guard. Imports the model and control layers, never the studies or interfaces."""
