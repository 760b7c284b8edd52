"""How `planner.plan` plans: the strategy settings around the SCP loop (which methods,
batches, dodges), apart from the loop's own knobs (`planner.scp.ScpOptions`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from planner.scp import ScpOptions

__all__ = ["PlanningOptions"]


@dataclass(frozen=True)
class PlanningOptions:
    """Strategy settings of `planner.plan`; the defaults are what it uses. The method itself
    (auto, whole, prioritized) is the scenario's `method` or `plan`'s argument."""

    scp: ScpOptions = field(default_factory=ScpOptions)
    """The SCP loop's own knobs, for every method."""
    dodge: bool = False
    """With fixed goals and at least `planner.dodge.DODGE_MIN_VEHICLES` vehicles, the whole
    fleet's first SCP iteration is linearised about the synchronised moves pushed apart by
    smooth dodges (`planner.dodge`) where they crowd; the whole fleet is planned again from
    the synchronised moves when that plan does not converge and verify. Off by default:
    measured faster on some crowds (sideways 100: 1.8x) and slower on others (random 256:
    1.6x), see docs/benchmarks/planner.md."""
    batch_size: int | None = None
    """Vehicles per prioritized batch; None: by the fleet's motion
    (`planner.prioritized.batch_size`: 1 in an obstacle-free crowd without a dominant
    motion, else `planner.scp.DEFAULT_BATCH`)."""
    batch_cost_share: bool = False
    """Each prioritized batch stops at its share of the scenario's `cost_threshold` (its
    vehicles over the fleet's), and the joined plan is taken only if its thrust cost exceeds
    the separation-free optimum by less than `cost_threshold`: then it is within that of the
    fleet's optimum, as a whole-fleet SCP stopped after a first iteration that changed the
    cost by less is (a replan's rule). False: each batch stops at the whole
    `cost_threshold`, and the joined plan's cost is not bounded."""

    def __post_init__(self) -> None:
        if self.batch_size is not None and (
                isinstance(self.batch_size, bool) or not isinstance(self.batch_size, int)
                or self.batch_size < 1):
            raise ValueError(f"batch_size: must be a whole number of vehicles >= 1, "
                             f"got {self.batch_size!r}")
