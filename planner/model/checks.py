"""Checks of single scenario fields, shared by every part of the scenario contract: numbers
in their ranges, vectors, ids and JSON objects' keys. Each raises `ScenarioError` naming the
field (a dotted path) and the reason."""

from __future__ import annotations

import difflib
import math
import unicodedata
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from planner.errors import ScenarioError
from planner.types import FloatArray

__all__ = ["MAX_ID_LENGTH", "RANGES", "check_id", "check_integer", "check_keys", "check_list",
           "check_number", "check_vector", "show_number", "unknown_key"]

#: Inclusive range of every number of a scenario, by field (`coordinate`: every position,
#: workspace corners, starts, goals; m). A value outside is refused, naming the field: the
#: ranges keep everything derived from the numbers (scaled distances and their squares,
#: costs, horizons, jerk) finite, so no magnitude can overflow a check into passing. They are
#: sanity bounds for a quadcopter fleet, not any vehicle's physical limits.
RANGES: dict[str, tuple[float, float]] = {
    "dt": (1e-3, 10.0),
    "min_separation": (1e-2, 100.0),
    "separation_margin": (0.0, 100.0),
    "separation_scale": (0.1, 10.0),
    "cost_threshold": (1e-9, 1e9),
    "coordinate": (-1e4, 1e4),
    "velocity_max": (1e-2, 100.0),
    "acceleration_max": (1e-2, 100.0),
    "jerk_max": (1e-2, 1e4),
    "thrust_min": (0.0, 100.0),
    "thrust_max": (0.0, 100.0),
    "body_rate_max": (1e-6, 100.0),
}

#: Longest vehicle id (characters): ids name CSV files and appear in every table.
MAX_ID_LENGTH = 64


def show_number(value: int | float) -> str:
    """A number for an error message, short even for an integer of a thousand digits."""
    if isinstance(value, int) and abs(value) >= 10**15:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    return f"{value:g}"


def check_number(value: Any, name: str, *, positive: bool = False, nonneg: bool = False,
                 within: str | None = None) -> float:
    """A finite float; with `within`, inside `RANGES[within]`. Raises `ScenarioError`
    naming the field `name` and the reason (the range, for a value outside it)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(name, f"must be a number, got {type(value).__name__}")
    if within is not None:
        lo, hi = RANGES[within]
        if not lo <= value <= hi:  # exact for integers of any size, false for NaN
            if isinstance(value, float) and not math.isfinite(value):
                raise ScenarioError(name, "must be a finite number")
            if positive and value <= 0:
                raise ScenarioError(name, f"must be positive, got {show_number(value)}")
            raise ScenarioError(name, f"must be between {lo:g} and {hi:g}, "
                                      f"got {show_number(value)}")
    try:
        x = float(value)
    except OverflowError:
        raise ScenarioError(name, f"must be a finite number, got {show_number(value)}") from None
    if not math.isfinite(x):
        raise ScenarioError(name, "must be a finite number")
    if positive and x <= 0:
        raise ScenarioError(name, f"must be positive, got {x:g}")
    if nonneg and x < 0:
        raise ScenarioError(name, f"must not be negative, got {x:g}")
    return x + 0.0  # -0.0 is 0.0


def check_integer(value: Any, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(name, f"must be an integer, got {type(value).__name__}")
    if isinstance(value, float) and not value.is_integer():
        raise ScenarioError(name, f"must be an integer, got {value}")
    if not lo <= value <= hi:
        raise ScenarioError(name, f"must be between {lo} and {hi}, got {show_number(value)}")
    return int(value)


def check_vector(value: Any, name: str, *, positive: bool = False,
                 within: str = "coordinate") -> FloatArray:
    """[x, y, z] of numbers each inside `RANGES[within]` (`check_number` per component)."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 3:
        raise ScenarioError(name, "must be a list of 3 numbers [x, y, z]")
    return np.array(
        [check_number(c, f"{name}[{i}]", positive=positive, within=within)
         for i, c in enumerate(value)], dtype=float
    )


#: Unicode categories refused in ids: control (C0, DEL, C1), format (bidi overrides,
#: zero-width), surrogates, line and paragraph separators.
_UNSAFE_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})


def check_id(value: Any, name: str) -> str:
    """A vehicle id: a non-empty string of at most `MAX_ID_LENGTH` printable characters
    (no control or invisible formatting characters: ids reach terminals, CSV files and
    logs). Raises `ScenarioError` naming the field."""
    if not isinstance(value, str) or not value.strip():
        raise ScenarioError(name, "must be a non-empty string")
    if len(value) > MAX_ID_LENGTH:
        raise ScenarioError(name, f"must be at most {MAX_ID_LENGTH} characters, "
                                  f"got {len(value)}")
    for index, char in enumerate(value):
        if unicodedata.category(char) in _UNSAFE_CATEGORIES:
            raise ScenarioError(name, f"must not contain control characters "
                                      f"(U+{ord(char):04X} at index {index})")
    return value


def check_keys(data: Any, allowed: set[str], name: str, required: Sequence[str], *,
               document: str = "scenario") -> None:
    """`data` is a JSON object with only `allowed` keys and every `required` one; `name` is its
    dotted path ("" for the whole `document`). Raises `ScenarioError` naming the key."""
    if not isinstance(data, Mapping):
        raise ScenarioError(name or document, "must be a JSON object")
    prefix = f"{name}." if name else ""
    for key in data:
        if key not in allowed:
            raise ScenarioError(f"{prefix}{key}", unknown_key(key, allowed))
    for key in required:
        if key not in data:
            raise ScenarioError(f"{prefix}{key}", "is required")


def unknown_key(key: object, allowed: Iterable[str]) -> str:
    """The reason for a key the contract does not know, with the nearest known key when one
    is close (a typo such as min_seperation: "did you mean 'min_separation'?")."""
    close = difflib.get_close_matches(str(key), sorted(allowed), n=1, cutoff=0.75)
    return f"unknown key (did you mean {close[0]!r}?)" if close else "unknown key"


def check_list(value: Any, name: str, what: str, at_most: int) -> Sequence[Any]:
    """`value` as a list of at most `at_most` `what`; ScenarioError naming `name` otherwise."""
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise ScenarioError(name, f"must be a list of {what}")
    if len(value) > at_most:
        raise ScenarioError(name, f"at most {at_most} {what}, got {len(value)}")
    return value
