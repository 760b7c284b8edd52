"""The separation-free optimum as the plan, when it is already separated.

The first QP (`planner.scp.first_qp`) minimises the thrust cost under the boxes and boundary
conditions only: a relaxation of the planning problem. When its solution also keeps every
pair at least R apart over continuous time, no separated plan can cost less, so it is the
optimum and the SCP loop has nothing to do. Under free assignment with CAPT's spacing this is
the usual case (`planner.methods.assignment`): the loop would only spend time and all-pairs memory
confirming it, which at show scale (16,000 vehicles, 128 million pairs) is most of the work.
"""

from __future__ import annotations

from planner.model.scenario import Scenario
from planner.result import IterationRecord, PlanStatus, Verification
from planner.scp.first_qp import FirstSolution
from planner.scp.loop import ScpOutcome, thrust_cost
from planner.scp.solvers import SOLVED
from planner.verification.verify import verify

__all__ = ["separated_first"]


def separated_first(scenario: Scenario, first: FirstSolution, seconds: float
                    ) -> tuple[ScpOutcome, Verification] | None:
    """The first QP's solution `first` (solved in `seconds`) as a converged outcome with its
    verification, when it solved and verifies (separation over continuous time, boxes,
    goals); else None (plan with the SCP loop, handing it `first`). Obstacles and fixed
    trajectories are the loop's business: None for them."""
    if scenario.obstacles or scenario.fixed:
        return None
    if first.status != SOLVED:
        return None
    p, v, a = first.positions, first.velocities, first.accelerations
    verification = verify(scenario, p, v, a)
    if not verification.verified:
        return None
    record = IterationRecord(0, thrust_cost(a), None, 0, first.qp_solves, 0, seconds)
    message = ("the separation-free optimum is separated over continuous time: it is the "
               "optimum")
    return ScpOutcome(PlanStatus.CONVERGED, message, p, v, a, [record], seconds), verification
