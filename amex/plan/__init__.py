"""Trajectories: the reference plan, its Gauss-Newton optimizer and phase-parametrized splines."""
