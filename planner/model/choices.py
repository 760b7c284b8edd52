"""The scenario's choices as Literals and their tuples of values: plain values (no numpy), so a
command line offers them without loading the scenario's parser (`planner.model.scenario`,
which re-exports them)."""

from __future__ import annotations

from typing import Literal, get_args

__all__ = ["ASSIGNMENTS", "Assignment"]

#: `assignment` values: "fixed" (vehicle n flies to its own goal) or "free" (any vehicle may
#: take any goal; see `planner.methods.assignment`).
Assignment = Literal["fixed", "free"]
ASSIGNMENTS: tuple[Assignment, ...] = get_args(Assignment)
