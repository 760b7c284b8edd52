"""fleetplan planner: collision-free trajectories for a quadcopter fleet by sequential convex
programming (Li, Zhu & Elahi 2024, after Augugliaro, Schoellig & D'Andrea 2012)."""
