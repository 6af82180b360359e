"""Controllers as Drake LeafSystems and what they need: the controller contract
(:mod:`.contract`), the LQI of paper section III with its compiled control step, the crank PD
baseline, the pose estimator, the density features, the tuners of the LQI's weights and the
learners of a feed-forward correction, and the linear model of the loop. Imports base, robot and
plant."""
