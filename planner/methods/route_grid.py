"""The grid over the workspace that routes are searched on (`planner.methods.routes`): its
cells, every cell centre's signed distance to the nearest obstacle, and the cells' 26-neighbour
graph for a set of free cells. The grid is built once per workspace and obstacles: the
batches of a prioritized plan share it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from planner.model.scenario import Scenario
from planner.types import BoolArray, FloatArray, IntArray

__all__ = ["CELL_PER_CLEARANCE", "MAX_CELLS", "MIN_CELL", "Grid", "build_grid"]

#: Most grid cells (the cell size grows to stay under it); the cells are at least MIN_CELL m
#: and half the clearance (finer cells than that find no more openings worth routing).
MAX_CELLS = 30_000
MIN_CELL = 0.15
CELL_PER_CLEARANCE = 0.5


@dataclass(frozen=True)
class Grid:
    """A cell grid over the workspace with each cell centre's distance to the obstacles."""

    origin: FloatArray
    """(3,) the centre of cell (0, 0, 0)."""
    spacing: FloatArray
    """(3,) cell size per axis (m)."""
    shape: tuple[int, int, int]
    distance: FloatArray
    """(cells,) signed distance of each centre to the nearest obstacle (flat, C order)."""
    nearest: IntArray
    """(cells,) that obstacle's index."""
    planar: bool = False
    """One layer of cells over the whole height: every obstacle spans the workspace's
    height, so the free space is the same at every altitude and routes are searched in the
    plane (six times fewer cells than the 3-D grid of the same cell size on the forests)."""
    graphs: dict[bytes, sp.csr_matrix] = field(default_factory=dict, compare=False,
                                                repr=False)
    """`graph` per free mask already built (a reused grid is asked for the same ones)."""

    @property
    def centres(self) -> FloatArray:
        idx = np.indices(self.shape).reshape(3, -1).T
        return self.origin + idx * self.spacing

    @property
    def half_diagonal(self) -> float:
        """Half a cell's diagonal: how much nearer than its centre a point of the cell can be
        to an obstacle (horizontally only on a planar grid: the distance is the same at every
        height there)."""
        return 0.5 * float(np.linalg.norm(self.spacing[:2] if self.planar else self.spacing))

    def cell_of(self, points: FloatArray) -> IntArray:
        """Flat index of the cell containing each point (clipped to the grid)."""
        idx = np.rint((points - self.origin) / self.spacing).astype(np.intp)
        idx = np.clip(idx, 0, np.array(self.shape) - 1)
        return np.asarray(np.ravel_multi_index(tuple(idx.T), self.shape), dtype=np.intp)

    def graph(self, free: BoolArray) -> sp.csr_matrix:
        """The 26-neighbour graph of the free cells, edges weighted by length (built once
        per mask)."""
        key = np.packbits(free).tobytes()
        built = self.graphs.get(key)
        if built is None:
            built = self.graphs[key] = self._graph(free)
        return built

    def _graph(self, free: BoolArray) -> sp.csr_matrix:
        shape = np.array(self.shape)
        grid_free = free.reshape(self.shape)
        rows, cols, weights = [], [], []
        for off in np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1)
                             for c in (-1, 0, 1)]):
            if tuple(off) <= (0, 0, 0):  # each undirected edge once
                continue
            lo = np.maximum(0, -off)
            hi = shape - np.maximum(0, off)
            here = grid_free[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
            there = grid_free[lo[0] + off[0]:hi[0] + off[0], lo[1] + off[1]:hi[1] + off[1],
                              lo[2] + off[2]:hi[2] + off[2]]
            both = np.argwhere(here & there) + lo
            a = np.ravel_multi_index(tuple(both.T), self.shape)
            b = np.ravel_multi_index(tuple((both + off).T), self.shape)
            rows.append(a)
            cols.append(b)
            weights.append(np.full(len(a), float(np.linalg.norm(off * self.spacing))))
        r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
        n = int(np.prod(shape))
        return sp.csr_matrix((np.concatenate([w, w]), (np.concatenate([r, c]),
                                                       np.concatenate([c, r]))), shape=(n, n))


#: The last grid built and what it was built from (the obstacles tuple itself, held so its
#: identity stays meaningful): the batches of a prioritized plan share one workspace.
_last_grid: list[tuple[Any, float, bytes, Grid]] = []


def build_grid(scenario: Scenario) -> Grid:
    """The grid over the workspace and every cell centre's distance to the obstacles (the
    last one again for the same obstacles, clearance and workspace)."""
    lim = scenario.limits
    bounds = lim.position_min.tobytes() + lim.position_max.tobytes()
    last = _last_grid[0] if _last_grid else None  # read once: safe beside other threads
    if last is not None and last[0] is scenario.obstacles and last[1] == scenario.clearance \
            and last[2] == bounds:
        return last[3]
    grid = _build_grid(scenario)
    _last_grid[:] = [(scenario.obstacles, scenario.clearance, bounds, grid)]
    return grid


def _build_grid(scenario: Scenario) -> Grid:
    lim = scenario.limits
    size = lim.position_max - lim.position_min
    cell = max(MIN_CELL, CELL_PER_CLEARANCE * scenario.clearance,
               float(np.prod(size) / MAX_CELLS) ** (1.0 / 3.0))
    shape = np.maximum(1, np.ceil(size / cell).astype(int))
    geometry = scenario.obstacle_set
    planar = bool(len(geometry) and (geometry.z[:, 0] <= lim.position_min[2]).all()
                  and (geometry.z[:, 1] >= lim.position_max[2]).all())
    if planar:
        shape[2] = 1
    spacing = size / shape
    origin = lim.position_min + 0.5 * spacing
    n = int(np.prod(shape))
    distance = np.full(n, np.inf)
    nearest = np.zeros(n, dtype=np.intp)
    reach = scenario.clearance + 2.0 * float(np.linalg.norm(spacing))
    for o in range(len(geometry)):
        lo = np.clip(np.floor((geometry.lo[o] - reach - origin) / spacing), 0, shape - 1)
        hi = np.clip(np.ceil((geometry.hi[o] + reach - origin) / spacing), 0, shape - 1)
        axes = [np.arange(int(a), int(b) + 1) for a, b in zip(lo, hi, strict=True)]
        idx = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        flat = np.asarray(np.ravel_multi_index(tuple(idx.T), tuple(shape)), dtype=np.intp)
        d = geometry.signed_distance(origin + idx * spacing, np.full(len(idx), o))
        closer = d < distance[flat]
        distance[flat[closer]] = d[closer]
        nearest[flat[closer]] = o
    return Grid(origin, spacing, (int(shape[0]), int(shape[1]), int(shape[2])), distance,
                nearest, planar)
