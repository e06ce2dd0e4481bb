"""The simulated benchmark: scenes, goal perception, the two-rate episode loop, episode metrics.

The scenes are Tasks 0-4 of the paper; the loop runs in MuJoCo (:mod:`amex.sim.episode`).
"""
