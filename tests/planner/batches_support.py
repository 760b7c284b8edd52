"""Helpers shared by the prioritized-batch tests: a fleet flying a swap, and the check
that every batch keeps R from the batches planned before it."""

from __future__ import annotations

import dataclasses

import numpy as np

from planner import plan
from planner.methods.prioritized import PrioritizedOutcome
from planner.model.scenario import Scenario
from planner.verification.verify import verify


def flying_swap(t: float) -> tuple[Scenario, np.ndarray, np.ndarray, np.ndarray]:
    """Six vehicles swapping across a 10 m square in 8 s (about 1.5 m/s), planned from rest,
    and every vehicle's state (position, velocity, acceleration) at flight time t."""
    angles = np.linspace(0.0, 2.0 * np.pi, 6, endpoint=False)
    ring = np.stack([5 + 4 * np.cos(angles), 5 + 4 * np.sin(angles),
                     1.2 + 0.3 * (np.arange(6) % 2)], axis=1)
    flying = plan({
        "name": "swap6", "dt": 0.2, "steps": 40, "min_separation": 1.0,
        "limits": {"position_min": [0, 0, 0], "position_max": [10, 10, 3],
                   "velocity_max": [2, 2, 2], "acceleration_max": [3, 3, 3]},
        "vehicles": [{"id": f"v{n}", "start": ring[n].tolist(),
                      "goal": ring[(n + 3) % 6].tolist()} for n in range(6)]}, method="whole")
    assert flying.ok
    state = flying.sample(np.array([t]))
    return flying.scenario, state.position[:, 0], state.velocity[:, 0], state.acceleration[:, 0]


def assert_each_batch_clear(work: Scenario, found: PrioritizedOutcome | str) -> None:
    """Every batch against everything planned before it keeps R over continuous time, as
    the verifier alone measures it."""
    assert isinstance(found, PrioritizedOutcome), found
    out = found.outcome
    for k in range(1, len(found.batches)):
        sel = np.concatenate(found.batches[:k + 1])
        sub = dataclasses.replace(work, vehicles=tuple(work.vehicles[j] for j in sel),
                                  starts=work.starts[sel], goals=work.goals[sel])
        check = verify(sub, out.positions[sel], out.velocities[sel], out.accelerations[sel])
        assert check.separated, (k, check.min_separation_continuous)
