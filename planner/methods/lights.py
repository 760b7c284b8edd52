"""A sequence's light design: each formation's colours and how the lights change on each leg.

A formation may carry `color`: one colour for every drone (``"#ff8800"`` or ``[255, 136, 0]``)
or a list of colours, one per position (slot) of the formation, in the order of its
`positions`. Once the free assignments are resolved, each vehicle takes the colour of the slot
it flies to. A formation without `color` keeps each drone's colour from the formation before
it (the first one: dark). A formation after the first may say, in `lights`, how the leg that
reaches it changes the colours: ``"fade"`` (from the previous colour to the new one over the
whole leg, the default), ``"hold"`` (keep the previous colour and switch on arrival) or
``"black"`` (fade out over the first half of the leg, in over the second). A sequence with no
`color` anywhere has no light design at all (`None`), and its plan is what it always was.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.errors import ScenarioError

__all__ = ["LIGHT_TRANSITIONS", "color_hex", "formation_colors", "leg_transition",
           "parse_color"]

#: How a leg changes the lights: name -> what it does (the contract's words).
LIGHT_TRANSITIONS: dict[str, str] = {
    "fade": "fade from the previous formation's colour to this one's over the leg",
    "hold": "keep the previous formation's colour over the leg, switch on arrival",
    "black": "fade to black over the first half of the leg, to this colour over the second",
}
DEFAULT_TRANSITION = "fade"
_HEX = re.compile(r"#[0-9a-fA-F]{6}")

Colors = NDArray[np.uint8]
"""(N, 3) red, green, blue in 0..255, one row per vehicle."""


def parse_color(value: Any, field: str) -> tuple[int, int, int]:
    """A colour: "#rrggbb" or [red, green, blue] integers 0..255; `ScenarioError` otherwise."""
    if isinstance(value, str):
        if not _HEX.fullmatch(value):
            raise ScenarioError(field, f'must be "#rrggbb" or [red, green, blue] (0..255), '
                                       f"got {value[:20]!r}")
        return int(value[1:3], 16), int(value[3:5], 16), int(value[5:7], 16)
    if (isinstance(value, Sequence) and len(value) == 3
            and all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255
                    for c in value)):
        return int(value[0]), int(value[1]), int(value[2])
    raise ScenarioError(field, 'must be "#rrggbb" or [red, green, blue] integers 0..255')


def color_hex(rgb: Sequence[int] | NDArray[np.uint8]) -> str:
    """The colour as "#rrggbb" (the form a plan's summary writes)."""
    return "#{:02x}{:02x}{:02x}".format(*(int(c) for c in rgb))


def _is_one_color(value: Any) -> bool:
    """A single colour rather than a list of them: a string, or three integers."""
    return isinstance(value, str) or (
        isinstance(value, Sequence) and len(value) == 3
        and all(isinstance(c, int) and not isinstance(c, bool) for c in value))


def formation_colors(raw: Mapping[str, Any], where: str, count: int,
                     order: NDArray[np.intp]) -> Colors | None:
    """The formation's `color` in vehicle order (vehicle n takes slot `order[n]`'s colour),
    or None when it has none. `ScenarioError` naming `where.color[i]`."""
    if "color" not in raw:
        return None
    value = raw["color"]
    field = f"{where}.color"
    if _is_one_color(value):
        return np.tile(np.array(parse_color(value, field), dtype=np.uint8), (count, 1))
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != count:
        raise ScenarioError(field, f"must be one colour for every drone, or a list of "
                                   f"{count} colours, one per position")
    slots = np.array([parse_color(c, f"{field}[{i}]") for i, c in enumerate(value)],
                     dtype=np.uint8)
    return slots[order]


def leg_transition(raw: Mapping[str, Any], where: str) -> str:
    """The formation's `lights` (how the leg reaching it changes the colours)."""
    value = raw.get("lights", DEFAULT_TRANSITION)
    if value not in LIGHT_TRANSITIONS:
        raise ScenarioError(f"{where}.lights", f"must be one of {', '.join(LIGHT_TRANSITIONS)}"
                                               f", got {str(value)[:20]!r}")
    return str(value)
