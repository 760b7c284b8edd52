"""The planner's exceptions, one tree rooted in `PlannerError`.

- `PlannerError`: base class of everything the planner raises on purpose.
  - `ScenarioError` (also a `FieldError`): the scenario is invalid (`ScenarioErrors`: with
    every problem of its settings at once).
  - `PlanFormatError` (also a `FieldError`): a plan JSON document is malformed.
  - `SolverError`: a QP solver failed in a way that is not a verdict on the problem
    (numerical trouble, missing backend). Infeasibility is a plan status, not an exception.

`FieldError` (a `ValueError`) is any bad input that names its field (a dotted path such as
``vehicles[2].goal``) and the reason; the GCS's fleet-file errors are `FieldError`s too, so
the CLI and the API report all of them the same way.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FieldError", "PlanFormatError", "PlannerError", "ScenarioError", "ScenarioErrors",
           "SolverError"]


class PlannerError(Exception):
    """Base class of the planner's errors."""


class FieldError(ValueError):
    """Bad input: `field` is the dotted path of the offending field, `reason` says why."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled with its fields (the constructor takes two arguments, `args` holds one),
        so an error raised in another process arrives as it was raised."""
        return (_rebuild_field_error, (type(self), self.args, self.__dict__))

    def to_dict(self) -> dict[str, str]:
        """JSON-friendly form used by the CLI and the REST API."""
        return {"field": self.field, "reason": self.reason}


def _rebuild_field_error(cls: type[FieldError], args: tuple[Any, ...],
                         state: dict[str, Any]) -> FieldError:
    """A pickled `FieldError` as it was (its constructor is not called again)."""
    error = cls.__new__(cls)
    error.args = args
    error.__dict__.update(state)
    return error


class ScenarioError(PlannerError, FieldError):
    """An invalid scenario."""


class ScenarioErrors(ScenarioError):
    """Several problems of one scenario found at once (`errors`, each a `FieldError`); its
    `field` and `reason` are the first's."""

    def __init__(self, errors: list[FieldError]) -> None:
        super().__init__(errors[0].field, errors[0].reason)
        self.errors = errors


class PlanFormatError(PlannerError, FieldError):
    """A malformed plan document."""


class SolverError(PlannerError, RuntimeError):
    """A QP backend failed for a reason other than infeasibility."""
