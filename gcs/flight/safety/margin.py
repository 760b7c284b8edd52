"""The safety margin a fleet needs, and whether a plan keeps it.

A real vehicle is not exactly where the plan puts it: its position estimate wanders (PX4 SIH
with GPS: about +-0.2 m hovering, 0.5 m GPS altitude noise) and it tracks its setpoints with
some error (0.42 m measured on SITL). If each vehicle of a fleet may be up to `e` off, two of
them may be 2e closer than planned. So a fleet file states `position_error` e, planning for
that fleet uses R + 2e (`scenario_for_fleet`), and the plan says so in its scenario's
`separation_margin` = 2e: the clearance the vehicles must keep is still R.

`check_margin` compares a plan's stated margin with what the fleet needs; `fleetplan fly`
and the executor refuse (or, with `margin_check: warn`, warn about) a plan short of it.
`separation_alarm_at` is where the live separation alarm stops the fleet: below the clearance
the vehicles must keep, never below the inflated planning separation.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

from planner import Plan
from planner.scenario import Scenario

__all__ = ["UNMARGINED_ALARM_BAND", "MarginCheck", "alarm_band", "check_margin",
           "scenario_for_fleet", "separation_alarm_at"]

#: The alarm band below R of a plan that states no margin (m): such a plan leaves the
#: vehicles' tracking error nowhere else (the mock flies a few cm inside R, SITL up to 0.3 m).
UNMARGINED_ALARM_BAND = 0.3


def scenario_for_fleet(scenario: dict[str, Any], position_error: float) -> dict[str, Any]:
    """A copy of a scenario JSON planned for a fleet with `position_error` e: min_separation
    R + 2e, `separation_margin` 2e (on top of any margin it already states)."""
    out = copy.deepcopy(scenario)
    margin = 2.0 * float(position_error)
    out["min_separation"] = float(out["min_separation"]) + margin
    out["separation_margin"] = float(out.get("separation_margin", 0.0)) + margin
    return out


@dataclass(frozen=True)
class MarginCheck:
    """A plan's separation margin against a fleet's need."""

    planned: float
    """The plan's `separation_margin` (m)."""
    needed: float | None
    """2 x the fleet's position_error (m); None when the fleet states none."""
    clearance: float
    """What the vehicles must keep: min_separation - separation_margin (m)."""

    @property
    def ok(self) -> bool:
        return self.needed is None or self.planned >= self.needed - 1e-9

    def message(self) -> str:
        if self.needed is None:
            return (f"the fleet states no position_error: margin not checked (plan margin "
                    f"{self.planned:g} m)")
        verdict = "enough" if self.ok else "too small"
        return (f"plan separation margin {self.planned:.2f} m, the fleet needs "
                f"{self.needed:.2f} m (2 x position_error): {verdict}"
                + ("" if self.ok else "; plan it for this fleet (fleetplan plan --fleet), "
                   "or fly it anyway with margin_check: warn"))

    def to_dict(self) -> dict[str, Any]:
        return {"planned": self.planned, "needed": self.needed, "clearance": self.clearance,
                "ok": self.ok}


def check_margin(plan: Plan, position_error: float | None) -> MarginCheck:
    """The plan's stated margin against 2 x `position_error` (None: nothing to check)."""
    scenario = plan.scenario
    return MarginCheck(scenario.separation_margin,
                       None if position_error is None else 2.0 * position_error,
                       scenario.min_separation - scenario.separation_margin)


def alarm_band(scenario: Scenario, band: float | None) -> float:
    """The alarm band below the clearance (m): `band` when stated, else 0 for a plan that
    states a margin (the margin is the vehicles' tolerance) and `UNMARGINED_ALARM_BAND`
    for one that does not."""
    if band is not None:
        return float(band)
    return 0.0 if scenario.separation_margin > 0 else UNMARGINED_ALARM_BAND


def required_separation(scenario: Scenario) -> float:
    """The clearance the vehicles must keep (m): R, the plan's min_separation less the
    separation_margin it was inflated by."""
    return scenario.min_separation - scenario.separation_margin


def separation_alarm_at(scenario: Scenario, band: float | None) -> float:
    """Two vehicles closer than this (the plan's metric, m) stop the whole fleet: the
    clearance they must keep (`required_separation`) minus `alarm_band`."""
    return required_separation(scenario) - alarm_band(scenario, band)
