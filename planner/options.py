"""How `planner.plan` plans: the SCP loop's own knobs (`ScpOptions`) and the strategy
settings around the loop (`PlanningOptions`: which methods, batches, dodges)."""

from __future__ import annotations

from dataclasses import dataclass, field

from planner.scp.obstacle_rows import SEED_FRACTION

__all__ = ["PlanningOptions", "ScpOptions"]


@dataclass(frozen=True)
class ScpOptions:
    """Knobs of the SCP loop itself; the defaults are what `planner.plan` uses (the choice of
    planning method is `planner.options.PlanningOptions`)."""

    continuous: bool = True
    """Interval rows (separation over continuous time) instead of the paper's step rows."""
    culling: bool = True
    """Rows only where needed (lazily completed). False: every pair at every step."""
    candidate_margin: float = 0.0
    """Pairs closer than R * (1 + margin) at the linearisation point seed a row."""
    violation_tolerance: float = 1e-6
    """A row or box broken by more than this is added to the QP (m, m/s, ...)."""
    split_above: int = 0
    """Groups of more vehicles are solved by block Gauss-Seidel sweeps (feasible, not
    necessarily optimal for the group's QP); 0 (the default): every group whole. Measured
    in the README (Performance): no clear gain at 1,000 vehicles, so off by default."""
    block_size: int = 32
    """Vehicles per block of a split group."""
    dual: bool = True
    """Solve each group's QP through its dual (`planner.scp.dual`, one variable per row; the
    same optimum) instead of the primal staged QP with the configured backend. Only with
    the PIQP backend; other backends always solve the primal, and so does a plan of more
    than `planner.scp.loop.DUAL_MAX_STEPS` steps, or a group whose dual is too large
    (`planner.scp.dual.MAX_PAIRS`) or did not solve (infeasible, ...)."""
    obstacle_seed: float = SEED_FRACTION
    """Obstacle rows within this many clearances of binding at the linearisation point
    start an iteration's QP (the rest are added when broken). More suits small QPs (the
    prioritized batches), where a re-solve costs more than the extra rows."""

    def __post_init__(self) -> None:
        if not 0.0 < self.obstacle_seed < float("inf"):
            raise ValueError(f"obstacle_seed: must be a positive number of clearances, "
                             f"got {self.obstacle_seed!r}")


@dataclass(frozen=True)
class PlanningOptions:
    """Strategy settings of `planner.plan`; the defaults are what it uses. The method itself
    (auto, whole, prioritized) is the scenario's `method` or `plan`'s argument."""

    scp: ScpOptions = field(default_factory=ScpOptions)
    """The SCP loop's own knobs, for every method."""
    dodge: bool = False
    """With fixed goals and at least `planner.methods.dodge.DODGE_MIN_VEHICLES` vehicles, the whole
    fleet's first SCP iteration is linearised about the synchronised moves pushed apart by
    smooth dodges (`planner.methods.dodge`) where they crowd; the whole fleet is planned again from
    the synchronised moves when that plan does not converge and verify. Off by default:
    measured faster on some crowds (sideways 100: 1.8x) and slower on others (random 256:
    1.6x), see docs/benchmarks/planner.md."""
    batch_size: int | None = None
    """Vehicles per prioritized batch; None: by the fleet's motion
    (`planner.methods.prioritized.batch_size`: 1 in an obstacle-free crowd without a dominant
    motion, else `planner.scp.loop.DEFAULT_BATCH`)."""
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
