"""Checks of a plan independent of the solver: continuous-time separation, clearance from
obstacles and fixed trajectories, boxes."""
