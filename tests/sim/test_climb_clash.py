"""`climb_clash`: mock vehicles set down under their starts climb straight up, so starts in
the air closer than R in x-y are refused before any mock starts; starts on the ground, or
apart, are not."""

from __future__ import annotations

from gcs.sim import climb_clash
from tests.flight.support import STACKED


def test_starts_stacked_closer_than_r_are_named_closest_first() -> None:
    starts = [v["start"] for v in STACKED["vehicles"]] + [[4.0, 4.0, 1.0], [4.0, 4.9, 2.5]]
    why = climb_clash(starts, ["low", "high", "c", "d"], 1.0)
    assert why is not None
    assert why.startswith("low and high start 0.55 m apart horizontally (at 1.08 m and 1.92 m)"
                          " (and 1 more pair), closer than the 1 m they must keep")
    assert "a fleet file" in why


def test_starts_apart_or_on_the_ground_climb_freely() -> None:
    assert climb_clash([[0.0, 0.0, 1.0], [1.0, 0.0, 3.0]], ["a", "b"], 1.0) is None
    assert climb_clash([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]], ["a", "b"], 1.0) is None
    assert climb_clash([[0.0, 0.0, 0.0], [0.5, 0.0, 2.0]], ["a", "b"], 1.0) is not None
