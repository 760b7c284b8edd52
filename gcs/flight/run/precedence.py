"""The order of a flight's commands: which of two conflicting commands wins.

Land overrides hold: a land that comes while the fleet holds (or is switching to Hold) is
applied after it; a hold that comes while the fleet lands is refused (`StateConflict`, 409)
with the reason. An abort (land or hold) overrides pause and replan: it ends the pause and
cancels a replan under way, and a pause, resume or replan that comes while the flight aborts
is refused. A repeated abort of the action in force is accepted and changes nothing.
The table is in docs/flying/operations.md ("Commands and their order").
"""

from __future__ import annotations

from gcs.errors import StateConflict
from gcs.phases import ABORT_ACTIONS

__all__ = ["ABORT_ACTIONS", "abort_in_force", "aborting_refusal"]


def abort_in_force(current: str | None, action: str, why: str = "") -> str:
    """The abort action in force once `action` is accepted after `current` (None: no abort
    yet). `StateConflict` naming ``action`` when `action` loses to `current`; `why` (the reason
    of the abort in force) goes into its reason."""
    if action not in ABORT_ACTIONS:
        raise ValueError(f"abort action must be one of {ABORT_ACTIONS}, got {action!r}")
    if current is None or ABORT_ACTIONS.index(action) >= ABORT_ACTIONS.index(current):
        return action
    because = f" ({why})" if why else ""
    raise StateConflict("action", f"the flight is already aborting with {current}{because}: "
                                  f"{current} overrides {action}")


def aborting_refusal(command: str, current: str, subject: str = "the flight") -> StateConflict:
    """The refusal of `command` (pause, resume, replan) while `subject` aborts with
    `current`: an abort overrides them."""
    return StateConflict("status", f"{subject} is aborting ({current}): an abort overrides "
                                   f"{command}")
