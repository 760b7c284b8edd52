"""Each drone's light changes from a planned sequence's light design.

A stitched sequence's plan carries its design in its `sequence` block
(`planner.methods.sequence`): every formation's `colors` {vehicle id: "#rrggbb"}, and from the
second formation on `lights`, how the leg that reaches it changes them ("fade", "hold",
"black"). The timeline's legs (`kind` "leg", `leg` k: formation k to k + 1, `start_s`,
`end_s`) say when. A drone shows formation 0's colour from time 0; on each leg it fades to
the next colour over the leg, holds its colour and switches on arrival, or fades out over the
first half and in over the second; holds keep the colour. A plan without a design has no
light changes (None): its drones stay dark (each program is a single END).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from gcs.errors import ExportError
from gcs.export.lightcode import BLACK, Change
from planner.errors import ScenarioError
from planner.methods.lights import LIGHT_TRANSITIONS, parse_color
from planner.result import Plan

__all__ = ["has_lights", "light_changes"]


def has_lights(plan: Plan) -> bool:
    """Whether the plan carries a light design (a sequence whose formations have colours)."""
    formations = (plan.sequence or {}).get("formations")
    return (isinstance(formations, Sequence) and bool(formations)
            and isinstance(formations[0], Mapping) and "colors" in formations[0])


def _color(formation: Mapping[str, Any], f: int, vid: str) -> tuple[int, int, int]:
    colors = formation.get("colors")
    field = f"sequence.formations[{f}].colors"
    if not isinstance(colors, Mapping) or vid not in colors:
        raise ExportError(field, f"has no colour for vehicle {vid!r}: plan the sequence "
                                 f"again with every formation's colours")
    try:
        return parse_color(colors[vid], f"{field}.{vid}")
    except ScenarioError as exc:
        raise ExportError(exc.field, exc.reason) from None


def _time(segment: Mapping[str, Any], key: str, k: int) -> float:
    value = segment.get(key)
    if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        raise ExportError(f"sequence.timeline[{k}].{key}", "must be a finite time (s) ≥ 0")
    return float(value)


def light_changes(plan: Plan, vid: str) -> list[Change] | None:
    """The drone's light changes in time order, None for a plan without a light design;
    `ExportError` naming the `sequence` field that is malformed."""
    if not has_lights(plan):
        return None
    assert plan.sequence is not None
    formations = plan.sequence["formations"]
    timeline = plan.sequence.get("timeline")
    if not isinstance(timeline, Sequence):
        raise ExportError("sequence.timeline", "must be a list of holds and legs")
    changes = [Change(0.0, 0.0, _color(formations[0], 0, vid))]
    for k, segment in enumerate(timeline):
        if not isinstance(segment, Mapping) or segment.get("kind") != "leg":
            continue
        leg = segment.get("leg")
        if not isinstance(leg, int) or not 0 <= leg < len(formations) - 1:
            raise ExportError(f"sequence.timeline[{k}].leg",
                              f"must be a leg number 0..{len(formations) - 2}")
        target = formations[leg + 1]
        if not isinstance(target, Mapping):
            raise ExportError(f"sequence.formations[{leg + 1}]", "must be a JSON object")
        color = _color(target, leg + 1, vid)
        start, end = _time(segment, "start_s", k), _time(segment, "end_s", k)
        how = target.get("lights", "fade")
        if how not in LIGHT_TRANSITIONS:
            raise ExportError(f"sequence.formations[{leg + 1}].lights",
                              f"must be one of {', '.join(LIGHT_TRANSITIONS)}")
        if how == "fade":
            changes.append(Change(start, end, color))
        elif how == "hold":
            changes.append(Change(end, end, color))
        else:
            middle = 0.5 * (start + end)
            changes += [Change(start, middle, BLACK), Change(middle, end, color)]
    return changes
