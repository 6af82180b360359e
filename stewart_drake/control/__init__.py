"""Controllers and their helpers as Drake LeafSystems: the LQI of paper section III, a crank PD
baseline, the density features and the ANN tuner (numpy inference). Imports only the model."""
