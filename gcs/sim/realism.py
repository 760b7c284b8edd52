"""The mock's behaviour presets (`gcs.sim.config.MockConfig.preset`) as a Literal and its tuple
of values: plain values (no numpy), so the CLI's `--realism` flags and the service's settings
offer them without loading the mock."""

from __future__ import annotations

from typing import Literal, get_args

__all__ = ["REALISMS", "Realism"]

#: "ideal" (exact state, no lag; the default) and "px4" (PX4 v1.16 SIH SITL's measured estimate
#: noise, lag and timings).
Realism = Literal["ideal", "px4"]
REALISMS: tuple[Realism, ...] = get_args(Realism)
