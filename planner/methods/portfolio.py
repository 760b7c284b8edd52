"""`auto`: plan with prioritized batches and the whole fleet at once; the first converged
and verified plan wins.

Neither method is fastest on every fleet (crowds crossing one point plan many times faster
in batches; random moves and some formations faster whole), and no cheap signal tells them
apart, so where both apply `auto` runs both, each in a forked process on its own core
(`planner.methods.race`): its time is the faster method's plus the fork and the hand-over of the
plan, and it plans whatever either method plans. The batches arm has no whole-fleet
fallback (the other arm is the whole fleet); the whole arm is `dodge` then `whole`, as in
process. Where batches decline (a fleet that fits one batch, free assignment, ...) there is
nothing to race: the table goes on in process with no overhead (`planner.methods.stages`). A small
obstacle-free fleet first gets a head start: the whole fleet in process for up to
HEAD_START_S, which plans the paper's cases in milliseconds without paying for the forks
(tens of milliseconds on a busy machine); only if that gives no verified plan do the two
methods race.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

from planner.methods.race import ArmResult, race
from planner.methods.stages import (
    DODGE,
    PRIORITIZED,
    SEPARATED_FIRST,
    WHOLE,
    Context,
    Run,
    Stage,
    TableResult,
    labelled,
    prioritized_declines,
    run_table,
)
from planner.result import Attempt, IterationProgress, IterationRecord, Outcome

__all__ = ["ARMS", "AUTO", "AUTO_TABLE", "HEAD_START", "HEAD_START_MAX_VEHICLES",
           "HEAD_START_S"]

#: Fleets of at most this many vehicles, without obstacles, get the head start: their SCP
#: iterations take milliseconds, so the budget is checked often enough (with obstacles the
#: batches are often much faster: pillar-circle8 0.26 s against 1.4 s whole).
HEAD_START_MAX_VEHICLES = 16
#: The head start's budget (s): the whole fleet of the paper's cases plans in 0.03 s.
HEAD_START_S = 0.15

#: The two arms `auto` races: their names and in-process tables.
ARMS: tuple[tuple[str, tuple[Stage, ...]], ...] = (
    ("prioritized", (PRIORITIZED,)),
    ("whole", (DODGE, WHOLE)),
)


def _arm(table: tuple[Stage, ...], ctx: Context
         ) -> Callable[[Callable[[Any], None]], TableResult]:
    """An arm for `race`: the table run on `ctx`, its progress sent to the parent."""
    def run(send: Callable[[Any], None]) -> TableResult:
        return run_table(table, dataclasses.replace(ctx, progress=send))
    return run


def _won(result: Any) -> bool:
    return isinstance(result, TableResult) and result.run is not None and result.run.ok


def _race(ctx: Context) -> Run:
    """Race the arms; the plan is the first converged and verified one, else the whole
    arm's plan (failed), else none (the table goes on in process)."""
    given = ctx.progress

    def forward(message: tuple[str, Any]) -> None:
        name, record = message
        if given is not None and isinstance(record, IterationRecord | IterationProgress):
            labelled(given, name)(record)

    results = race([(name, _arm(table, ctx)) for name, table in ARMS], _won, forward)
    return _merged(results)


def _merged(results: Sequence[ArmResult]) -> Run:
    """The race's plan and every arm's attempts (a cancelled or broken arm: one record)."""
    winner = next((r for r in results if _won(r.value)), None)
    attempts: list[Attempt] = []
    for result in results:
        if isinstance(result.value, TableResult):
            attempts += result.value.attempts
        elif result.cancelled:
            attempts.append(Attempt(result.name, Outcome.CANCELLED,
                                    f"the {winner.name if winner else 'other'} plan came "
                                    f"first", result.seconds))
        else:
            attempts.append(Attempt(result.name, Outcome.FAILED,
                                    result.error or "no result", result.seconds))
    chosen = winner or next((r for r in results if isinstance(r.value, TableResult)
                             and r.value.run is not None), None)
    if chosen is None:
        return Run(None, None, "no arm gave a plan", attempts=attempts)
    table: TableResult = chosen.value
    assert table.run is not None
    return dataclasses.replace(table.run, attempts=attempts, method=table.method)


class _OverBudget(Exception):
    """Raised from the head start's progress callback when its budget is spent."""


def _head_start_declines(ctx: Context) -> str | None:
    why = prioritized_declines(ctx)
    if why is not None:
        return f"no race to avoid: batches do not apply ({why})"
    if ctx.work.obstacles:
        return "obstacles: the methods race at once"
    if len(ctx.work.vehicles) > HEAD_START_MAX_VEHICLES:
        return f"more than {HEAD_START_MAX_VEHICLES} vehicles: the methods race at once"
    return None


def _head_start(ctx: Context) -> Run:
    """The whole fleet in process, stopped after the first iteration past HEAD_START_S."""
    began = time.perf_counter()
    given = ctx.progress

    def watch(record: IterationRecord | IterationProgress) -> None:
        if given is not None:
            given(record)
        if time.perf_counter() - began > HEAD_START_S:
            raise _OverBudget

    try:
        run = WHOLE.run(dataclasses.replace(ctx, progress=watch))
    except _OverBudget:
        return Run(None, None, f"no verified plan within its {HEAD_START_S:g} s")
    return dataclasses.replace(run, method="whole")


#: The whole fleet in process before any race (see the module docstring).
HEAD_START = Stage("head_start", _head_start_declines, _head_start, method="whole")
#: The portfolio as a stage: it declines where batches decline, and its record then says
#: so under their name; when it runs, its arms' own records stand for it.
AUTO = Stage("prioritized", prioritized_declines, _race, final=True)
#: What `auto` runs: the portfolio where it applies, else the whole fleet in process.
AUTO_TABLE = (SEPARATED_FIRST, HEAD_START, AUTO, DODGE, WHOLE)
