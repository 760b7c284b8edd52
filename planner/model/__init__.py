"""The planning problem: the scenario contract and its field checks, obstacles, fixed
trajectories, dynamics and flatness (thrust, body rates)."""
