"""The planning methods as a table of stages, and the one loop that runs a table.

A stage is one way to plan the fleet: the separation-free optimum taken as it is
(`separated_first`), prioritized batches (`prioritized`), the whole fleet linearised about
dodged moves first (`dodge`), the whole fleet's SCP (`whole`). Given the planning context a
stage either declines, with a reason, or runs, with an outcome. `run_table` runs a table in
order and stops at the first stage whose plan converged and verified, or at a final stage
(its plan is the plan whatever it is); it records every stage as an `Attempt`. Which table a
method runs is `table_for`; `auto` races two of them (`planner.methods.portfolio`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from planner.methods.dodge import DODGE_MIN_VEHICLES, dodged_moves
from planner.methods.prioritized import PrioritizedOutcome, batch_size, plan_batches
from planner.methods.separated_first import separated_first
from planner.model.scenario import Scenario
from planner.options import PlanningOptions
from planner.result import (
    Attempt,
    IterationProgress,
    IterationRecord,
    Outcome,
    PlanStatus,
    Progress,
    Verification,
)
from planner.scp.first_qp import FirstSolution, solve_first_qp, straight_moves
from planner.scp.loop import ScpOutcome, run_scp, thrust_cost
from planner.scp.solvers import SOLVED, QPSolver
from planner.types import FloatArray
from planner.verification.verify import verify

__all__ = ["DODGE", "PRIORITIZED", "SEPARATED_FIRST", "WHOLE", "Context", "Run", "Stage",
           "TableResult", "labelled", "run_table", "table_for"]

Trajectories = tuple[FloatArray, FloatArray, FloatArray]


@dataclass
class Context:
    """What every stage plans from: the scenario with its goals assigned, the solver, the
    settings, and what earlier stages computed that later ones reuse."""

    work: Scenario
    """The scenario with each vehicle's goal assigned (`Scenario.assigned`)."""
    free: bool
    """The scenario's goals were assigned freely (CAPT's moves seed the whole fleet)."""
    backend: QPSolver
    options: PlanningOptions
    progress: Progress | None
    first_qp: tuple[FirstSolution, float] | None = None
    """The separation-free first QP and its time, when it was solved before the loop."""
    guess: Trajectories | None = None
    """The whole fleet's first linearisation point (CAPT's straight moves under free
    assignment); None: the separation-free optimum."""


@dataclass
class Run:
    """What a stage that ran produced: trajectories (or none) and their verification."""

    outcome: ScpOutcome | None
    verification: Verification | None
    reason: str = ""
    """Why it failed (empty when its plan converged and verified)."""
    attempts: list[Attempt] | None = None
    """A stage that runs other tables (the portfolio) gives their attempts instead of its
    own record."""
    method: str | None = None
    """The method that produced `outcome`, when not the stage itself (the portfolio)."""

    @property
    def ok(self) -> bool:
        """Converged and verified."""
        return (self.outcome is not None and self.outcome.status == PlanStatus.CONVERGED
                and self.verification is not None and self.verification.verified)


@dataclass(frozen=True)
class Stage:
    """One planning method: `decline` says why it does not apply (None: it does), `run`
    plans. A `final` stage's plan ends the table even when it failed."""

    name: str
    decline: Callable[[Context], str | None]
    run: Callable[[Context], Run]
    final: bool = False
    method: str | None = None
    """The method its progress records are labelled with, when not its name."""


@dataclass
class TableResult:
    """The plan a table produced (None: no stage gave one), its method and the attempts."""

    run: Run | None
    method: str | None
    attempts: list[Attempt]


def run_table(table: Sequence[Stage], ctx: Context) -> TableResult:
    """Run the stages of `table` in order (see the module docstring). Each stage's progress
    records carry its name (`IterationRecord.method`)."""
    attempts: list[Attempt] = []
    given = ctx.progress
    try:
        for stage in table:
            began = time.perf_counter()
            why = stage.decline(ctx)
            if why is not None:
                attempts.append(Attempt(stage.name, Outcome.DECLINED, why,
                                        time.perf_counter() - began))
                continue
            ctx.progress = None if given is None else labelled(given,
                                                                stage.method or stage.name)
            run = stage.run(ctx)
            ctx.progress = given
            seconds = time.perf_counter() - began
            ended = run.ok or (stage.final and run.outcome is not None)
            if run.attempts is not None:
                attempts.extend(run.attempts)
            elif run.ok:
                assert run.outcome is not None
                attempts.append(Attempt(stage.name, Outcome.WON, run.outcome.message, seconds))
            else:
                reason = run.reason or (run.outcome.message if run.outcome else "no plan")
                attempts.append(Attempt(stage.name, Outcome.FAILED, reason, seconds))
            if ended:
                return TableResult(run, run.method or stage.name, attempts)
    finally:
        ctx.progress = given
    return TableResult(None, None, attempts)


def labelled(progress: Progress, method: str) -> Progress:
    """`progress` with every record not yet labelled labelled as `method`'s."""
    def forward(record: IterationRecord | IterationProgress) -> None:
        progress(record if record.method is not None
                 else dataclasses.replace(record, method=method))
    return forward


def _verified(work: Scenario, outcome: ScpOutcome) -> Run:
    """`outcome` with its independent verification (none for an infeasible one)."""
    if outcome.status == PlanStatus.INFEASIBLE:
        return Run(outcome, None, outcome.message)
    verification = verify(work, outcome.positions, outcome.velocities, outcome.accelerations)
    run = Run(outcome, verification)
    if not run.ok:
        run.reason = "; ".join([outcome.message, *verification.failures()])
    return run


# ---------------------------------------------------------------- separated first


def _separated_first_declines(ctx: Context) -> str | None:
    if ctx.first_qp is None:
        return "fixed goals: the separation-free optimum is tried under free assignment only"
    if ctx.work.obstacles or ctx.work.fixed:
        return "obstacles or fixed trajectories: the SCP loop's business"
    return None


def _separated_first(ctx: Context) -> Run:
    assert ctx.first_qp is not None
    direct = separated_first(ctx.work, *ctx.first_qp)
    if direct is None:
        return Run(None, None, "the separation-free optimum is not separated over continuous "
                               "time (or did not solve)")
    outcome, verification = direct
    if ctx.progress is not None:
        ctx.progress(outcome.iterations[0])
    return Run(outcome, verification)


SEPARATED_FIRST = Stage("separated_first", _separated_first_declines, _separated_first)


# ---------------------------------------------------------------- prioritized batches


def _dodges(ctx: Context) -> bool:
    """Is the whole fleet's first linearisation point the dodged moves? Asked for, fixed
    goals, a large fleet of straight rest-to-rest moves in free space only (routes seed
    obstacle scenarios; fixed trajectories and start velocities are not straight moves'
    business)."""
    work = ctx.work
    return (ctx.options.dodge and not ctx.free and len(work.vehicles) >= DODGE_MIN_VEHICLES
            and not work.obstacles and not work.fixed and work.start_velocities is None)


def prioritized_declines(ctx: Context) -> str | None:
    """Why prioritized batches do not apply to `ctx` (None: they do): they plan fixed-goal
    moves of a fleet of more than one batch (from rest or a moving state, around its fixed
    trajectories)."""
    size = batch_size(ctx.work, ctx.options.batch_size)
    if len(ctx.work.vehicles) <= size:
        return f"{len(ctx.work.vehicles)} vehicles fit in one batch of {size}"
    if ctx.free:
        return "free assignment plans from CAPT's straight moves"
    if _dodges(ctx):
        return "the dodged first linearisation point was asked for too"
    return None


def _above_free(work: Scenario, backend: QPSolver, accelerations: FloatArray) -> float:
    """How much more thrust cost `accelerations` take than `work`'s separation-free optimum
    (a lower bound on every plan's cost): at most that far from the optimum."""
    free = solve_first_qp(work, backend)
    if free.status != SOLVED:
        return float("inf")
    return thrust_cost(accelerations) - thrust_cost(free.accelerations)


def _prioritized(ctx: Context) -> Run:
    work, options = ctx.work, ctx.options
    batched = plan_batches(work, ctx.backend, options.scp, ctx.progress, options.batch_size,
                           cost_share=options.batch_cost_share)
    if not isinstance(batched, PrioritizedOutcome):
        return Run(None, None, batched)
    outcome = batched.outcome
    verification = verify(work, outcome.positions, outcome.velocities, outcome.accelerations)
    if not verification.verified:
        return Run(None, None, "the joined batches failed verification: "
                               + "; ".join(verification.failures()))
    if options.batch_cost_share:
        above = _above_free(work, ctx.backend, outcome.accelerations)
        if not above < work.cost_threshold:
            return Run(None, None, f"the joined batches cost {above:.3g} above the "
                                   f"separation-free optimum, not less than cost_threshold "
                                   f"{work.cost_threshold:g}")
    return Run(outcome, verification)


PRIORITIZED = Stage("prioritized", prioritized_declines, _prioritized)


# ---------------------------------------------------------------- whole fleet


def _dodge_declines(ctx: Context) -> str | None:
    if not ctx.options.dodge:
        return "not asked for (PlanningOptions.dodge)"
    if not _dodges(ctx):
        return (f"applies to fixed-goal moves from rest in free space of at least "
                f"{DODGE_MIN_VEHICLES} vehicles")
    return None


def _dodge(ctx: Context) -> Run:
    found = dodged_moves(ctx.work, straight_moves(ctx.work))
    if found is None:
        return Run(None, None, "no pair of the straight moves crowds: nothing to dodge")
    outcome = run_scp(ctx.work, ctx.backend, ctx.options.scp, ctx.progress, found[0])
    return _verified(ctx.work, outcome)


def _whole(ctx: Context) -> Run:
    outcome = run_scp(ctx.work, ctx.backend, ctx.options.scp, ctx.progress, ctx.guess,
                      ctx.first_qp)
    return _verified(ctx.work, outcome)


DODGE = Stage("dodge", _dodge_declines, _dodge)
WHOLE = Stage("whole", lambda ctx: None, _whole, final=True)


def table_for(method: str) -> tuple[Stage, ...]:
    """The stages a method runs in process: `whole` never tries batches; `prioritized` tries
    them before the whole fleet. (`auto` races them: `planner.methods.portfolio`.)"""
    if method == "prioritized":
        return (SEPARATED_FIRST, PRIORITIZED, DODGE, WHOLE)
    return (SEPARATED_FIRST, DODGE, WHOLE)
