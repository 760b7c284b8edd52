"""One in-flight replan's record: what was asked, when it switches, and what became of it.

`ReplanRecord` is created planning by `gcs.flight.replan.replan.Replanner`, then ends switched
or missed (`switched`, `missed`); `document` is its JSON form (`gcs.documents.ReplanDocument`)
for the snapshot, the REST API and the flight record.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs.documents import ReplanDocument
from gcs.phases import DropAction, ReplanStatus

__all__ = ["ReplanRecord", "Switch"]


@dataclass(frozen=True)
class Switch:
    """What a switched replan put in force."""

    horizon: float
    """The new plan's horizon (s)."""
    request_to_switch_s: float
    """From the request to the switch tick (s)."""
    min_separation_planned: float | None
    """The new plan's verified minimum separation (None: not verified)."""
    separation_kept: float
    """The separation the replan planned with (m)."""


@dataclass
class ReplanRecord:
    """One replan of a flight (flight times in s; see `gcs.documents.ReplanDocument`)."""

    id: int
    requested_at: float | None
    switch_time: float
    switch_tick: int
    lead_s: float
    goals: dict[str, list[float]]
    drop: list[str]
    drop_action: DropAction
    reason: str | None
    vehicles: list[str]
    """The vehicles it plans."""
    fixed: list[str]
    """The vehicles off the plans it plans around."""
    faulty: list[str]
    status: ReplanStatus = ReplanStatus.PLANNING
    planning_s: float | None = None
    why: str | None = None
    """Why it missed."""
    switch: Switch | None = None

    def missed(self, why: str) -> None:
        """Not flown: the fleet goes on with its plan."""
        self.status, self.why = ReplanStatus.MISSED, why

    def switched(self, switch: Switch) -> None:
        """Flown from its switch tick."""
        self.status, self.switch = ReplanStatus.SWITCHED, switch

    def document(self) -> ReplanDocument:
        """The JSON-ready object (a fresh dict: the caller may keep it)."""
        doc: ReplanDocument = {
            "id": self.id, "status": self.status, "requested_at": self.requested_at,
            "switch_time": self.switch_time, "switch_tick": self.switch_tick,
            "lead_s": self.lead_s, "planning_s": self.planning_s,
            "goals": {vid: list(g) for vid, g in self.goals.items()},
            "drop": list(self.drop), "drop_action": self.drop_action, "reason": self.reason,
            "vehicles": list(self.vehicles), "fixed": list(self.fixed),
            "faulty": list(self.faulty), "why": self.why,
            "horizon": None if self.switch is None else self.switch.horizon,
        }
        if self.switch is not None:
            doc["request_to_switch_s"] = self.switch.request_to_switch_s
            doc["min_separation_planned"] = self.switch.min_separation_planned
            doc["separation_kept"] = self.switch.separation_kept
        return doc
