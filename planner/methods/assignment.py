"""Goal assignment for `"assignment": "free"` and its CAPT initial guess (Turpin, Michael &
Kumar 2014).

Long: one algorithm: the certified sparse assignment and its dense fallback.

The assignment minimises the total squared distance from starts to goals in the separation
metric ||diag(1/scale) d|| (plain Euclidean for the default scale). Such an assignment makes
every pair's start and goal displacements r0 = S(s_i - s_j), r1 = S(g_i - g_j) satisfy
r0'r1 >= 0 (else swapping the two goals would be cheaper), so on synchronised straight moves
r(t) = (1 - phi) r0 + phi r1 with a common phi(t) in [0, 1],
||r(t)||^2 >= (1 - phi)^2 ||r0||^2 + phi^2 ||r1||^2 >= D^2 / 2 where D is the smallest
start-start or goal-goal distance: the moves keep pairs at least D / sqrt(2) apart,
collision-free whenever D >= sqrt(2) R (CAPT's spacing condition). The moves themselves are
`planner.scp.first_qp.straight_moves`.

Below `DENSE_BELOW` vehicles the Hungarian method solves the dense N x N problem
(`scipy.optimize.linear_sum_assignment`). Above it nothing N x N is built. Both sets are
centred and scaled (the optimum does not change), and a sparse candidate graph is formed: each
start's nearest goals and each goal's nearest starts, three sort-order matchings (so a full
matching always exists) and, from N >= `COARSE_BELOW`, the goals near where the moves of a
solved random quarter of the points predict each start to go. The graph is solved exactly
(`_match`: lapmod, or scipy on whole quanta where lapmod refuses the weights), dual potentials
u, v are computed for that optimum, and all N^2 edges are checked against them: min_j (c_ij -
v_j) is a nearest-neighbour query among goals lifted to (g_j, sqrt(max v - v_j)). Edges with
negative reduced cost join the graph and the loop repeats; when none is left, the assignment is
optimal over all N^2 edges (LP duality, up to `TOLERANCE` per edge). Any v gives the bound
sum_i min_j (c_ij - v_j) + sum v, so `solve_assignment` always reports how far from optimal the
order can be. An unproven result (round cap, float trouble) falls back to the dense method
below `DENSE_FALLBACK` vehicles.
"""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np

from planner.types import FloatArray, IntArray

__all__ = ["CAPT_SPACING", "DENSE_BELOW", "NEIGHBOURS", "TOLERANCE", "Assignment",
           "assign_goals", "capt_spacing_holds", "certify", "matcher", "solve_assignment"]


#: Starts and goals this many R apart (separation metric) make CAPT moves collision-free.
CAPT_SPACING = float(np.sqrt(2.0))
#: Fleets smaller than this use the dense Hungarian method (N x N costs, cubic time).
DENSE_BELOW = 1200
#: Candidate goals per start (and starts per goal) in the sparse graph's first round, and the
#: best-reduced-cost goals added per start whose certificate fails in later rounds.
NEIGHBOURS = 8
#: Reduced-cost tolerance of the certificate, in the centred and scaled costs (points at unit
#: root-mean-square radius): an edge counts as improving when it is below -TOLERANCE.
TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True)
class Assignment:
    """A solved assignment and its optimality certificate.

    order[n]: the goal of start n. cost: the total squared scaled distance. lower_bound: a
    bound no assignment can beat (the LP dual value); cost - lower_bound is how far from
    optimal the order can be. proven: every edge's reduced cost is >= -TOLERANCE, so the order
    is optimal (the dense method is exact by construction). method: "dense" or "sparse";
    rounds and edges: the sparse loop's solves and final candidate edges (0 for dense)."""

    order: IntArray
    cost: float
    lower_bound: float
    proven: bool
    method: str
    rounds: int = 0
    edges: int = 0

    @property
    def gap(self) -> float:
        """cost - lower_bound: by how much the order may exceed the optimum (>= 0)."""
        return max(0.0, self.cost - self.lower_bound)


def assign_goals(starts: FloatArray, goals: FloatArray, scale: FloatArray | None = None,
                 *, dense_below: int = DENSE_BELOW) -> IntArray:
    """order[n]: the index of the goal vehicle n flies to, minimising the total squared
    (scaled) distance. Deterministic for given inputs; see `solve_assignment`. A result not
    proven optimal (none so far) comes with a RuntimeWarning giving its gap bound."""
    solved = solve_assignment(starts, goals, scale, dense_below=dense_below)
    if not solved.proven:
        warnings.warn(f"free assignment of {len(solved.order)} vehicles not proven optimal: "
                      f"it may exceed the optimum by {solved.gap:.3g} (total squared "
                      f"distance {solved.cost:.6g})", RuntimeWarning, stacklevel=2)
    return solved.order


def solve_assignment(starts: FloatArray, goals: FloatArray, scale: FloatArray | None = None,
                     *, dense_below: int = DENSE_BELOW, neighbours: int = NEIGHBOURS
                     ) -> Assignment:
    """The optimal assignment of starts to goals (total squared scaled distance) with its
    certificate: dense Hungarian below `dense_below` vehicles, else the certified sparse
    loop. Raises ValueError when the two sets differ in size."""
    starts = np.asarray(starts, dtype=float)
    goals = np.asarray(goals, dtype=float)
    if starts.shape != goals.shape:
        raise ValueError(f"starts {starts.shape} and goals {goals.shape} differ in shape")
    s = np.ones(starts.shape[1]) if scale is None else np.asarray(scale, dtype=float)
    a, b = starts / s, goals / s
    n = len(a)
    if n < max(dense_below, 2):
        return _dense(a, b)
    solved = _sparse(a, b, max(1, neighbours))
    if not solved.proven and n < DENSE_FALLBACK:
        return _dense(a, b)
    return solved


def _total(a: FloatArray, b: FloatArray, order: IntArray) -> float:
    return float(np.sum((a - b[order]) ** 2))


def _dense(a: FloatArray, b: FloatArray) -> Assignment:
    """The Hungarian method on the full N x N cost matrix: exact."""
    from scipy.optimize import linear_sum_assignment  # on first use: slow to import

    # ||a||^2 + ||b||^2 - 2 a.b, without an (N, N, 3) temporary.
    cost = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    rows, cols = linear_sum_assignment(cost)
    order = np.empty(len(a), dtype=np.intp)
    order[rows] = cols
    total = _total(a, b, order)
    return Assignment(order, total, total, True, "dense")


def _normalised(points: FloatArray) -> tuple[FloatArray, float]:
    """The points centred on their mean and scaled to unit root-mean-square radius, and that
    radius. Translating or positively scaling either set adds a constant to (or multiplies)
    every assignment's cost a'b term, so the optimum stays the same."""
    centred = points - points.mean(axis=0)
    radius = float(np.sqrt(np.mean(np.sum(centred * centred, axis=1))))
    radius = radius if radius > 0.0 else 1.0
    return centred / radius, radius


def _sparse(a0: FloatArray, b0: FloatArray, k: int) -> Assignment:
    """The certified sparse loop (module docstring) on the centred and scaled points."""
    a, ra = _normalised(a0)
    b, rb = _normalised(b0)
    solved = _certified(a, b, k)
    total = _total(a0, b0, solved.order)
    gap = solved.gap * ra * rb  # the costs differ by ra rb c'[i, j] + f[i] + g[j]
    return Assignment(solved.order, total, total - gap, solved.proven, "sparse",
                      solved.rounds, solved.edges)


@dataclasses.dataclass(frozen=True)
class _Solved:
    """A sparse solve in the coordinates it was given: its order, dual potentials, the gap
    between its cost and the dual bound, whether every edge passed the check, rounds and
    candidate edges."""

    order: IntArray
    u: FloatArray
    v: FloatArray
    gap: float
    proven: bool
    rounds: int
    edges: int


#: From this size the sparse loop first solves a random quarter of the points (recursively),
#: adds the goals its moves predict to the candidates and starts from its potentials.
COARSE_BELOW = 2000
#: Coarse starts (goals) whose moves predict where a start's goal (a goal's start) lies.
PREDICTIONS = 3
#: Candidate-graph rounds before the sparse loop gives up proving (it has never needed 15).
MAX_ROUNDS = 60
#: Threads of the k-d tree queries (-1: every core; the queries are independent per point).
WORKERS = -1
#: An unproven sparse result below this many vehicles is replaced by the dense method.
DENSE_FALLBACK = 3000
#: Resolution of the sparse matcher's weights, in the centred and scaled costs. scipy's sparse
#: Jonker-Volgenant stalls on float weights full of near-ties (lattice formations such as a
#: grid onto a torus or a cube at 2,000 vehicles: its augmenting row reduction then lowers
#: prices a few ulps at a time) and solves whole multiples of this in about a second. The
#: certificate still judges the matching on the exact costs (to `TOLERANCE`).
WEIGHT_QUANTUM = 1e-6
#: A round whose matching is optimal only to the quantum (some edge of its own graph has a
#: negative exact reduced cost) is solved again on a quantum 1,000 times finer, down to this.
FINEST_QUANTUM = 1e-12


def _lifted_best(a: FloatArray, b: FloatArray, v: FloatArray, k: int
                 ) -> tuple[FloatArray, IntArray]:
    """For every a[i], the k smallest |a_i - b_j|^2 - v_j over all j and their j, through the
    nearest neighbours of (a_i, 0) among the lifted (b_j, sqrt(max v - v_j))."""
    from scipy.spatial import cKDTree

    top = float(v.max())
    tree = cKDTree(np.column_stack([b, np.sqrt(np.maximum(top - v, 0.0))]))
    dist, best = tree.query(np.column_stack([a, np.zeros(len(a))]), min(k, len(b)),
                            workers=WORKERS)
    dist = np.asarray(dist).reshape(len(a), -1)
    return dist * dist - top, np.asarray(best, dtype=np.intp).reshape(len(a), -1)


def _first_graph(a: FloatArray, b: FloatArray, k: int
                 ) -> tuple[IntArray, FloatArray, FloatArray]:
    """The first candidate graph of the sparse loop, as sorted edge keys (start * N + goal),
    and the potentials (u, v) it starts from: three sort-order matchings, the `k` nearest
    goals of each start and starts of each goal, and from `COARSE_BELOW` points the goals a
    solved random quarter's moves predict (module docstring)."""
    from scipy.spatial import cKDTree

    n = len(a)
    kk = min(k, n)
    everyone = np.repeat(np.arange(n), kk)
    keys = []
    for axis in range(a.shape[1]):  # 1-D sorted matchings: a full matching always exists
        keys.append(np.argsort(a[:, axis], kind="stable") * n
                    + np.argsort(b[:, axis], kind="stable"))
    if n >= COARSE_BELOW:
        # solve a random quarter, then look for each start's goal around where its nearest
        # coarse starts' moves would take it (and for each goal's start likewise)
        rng = np.random.default_rng(n)
        pa, pb = rng.permutation(n)[:n // 4], rng.permutation(n)[:n // 4]
        ca, cb = a[pa], b[pb]
        coarse = _certified(ca, cb, k)
        move = cb[coarse.order] - ca
        back = np.empty_like(move)
        back[coarse.order] = move
        spread = max(1, kk // 2)
        goal_tree, start_tree = cKDTree(b), cKDTree(a)
        _, near = cKDTree(ca).query(a, PREDICTIONS)
        _, hits = goal_tree.query((a[:, None, :] + move[near]).reshape(-1, a.shape[1]),
                                  spread, workers=WORKERS)
        keys.append(np.repeat(np.arange(n), PREDICTIONS * spread) * n
                    + np.asarray(hits).reshape(-1))
        _, near = cKDTree(cb).query(b, PREDICTIONS)
        _, hits = start_tree.query((b[:, None, :] - back[near]).reshape(-1, b.shape[1]),
                                   spread, workers=WORKERS)
        keys.append(np.asarray(hits).reshape(-1) * n
                    + np.repeat(np.arange(n), PREDICTIONS * spread))
    # nearest goals of each start and nearest starts of each goal
    _, near_goals = cKDTree(b).query(a, kk, workers=WORKERS)
    _, near_starts = cKDTree(a).query(b, kk, workers=WORKERS)
    keys += [everyone * n + np.asarray(near_goals).reshape(-1),
             np.asarray(near_starts).reshape(-1) * n + everyone]
    u, v = np.zeros(n), np.zeros(n)
    if n >= COARSE_BELOW:
        # warm start: the coarse start potentials' c-transform prices the goals, whose
        # c-transform prices the starts; such (u, v) are feasible on all N^2 edges
        v = _lifted_best(b, ca, coarse.u, 1)[0][:, 0]
        u_cost, u_goal = _lifted_best(a, b, v, 1)
        u = u_cost[:, 0]
        keys.append(np.arange(n) * n + u_goal[:, 0])
    return np.unique(np.concatenate(keys)), u, v


def _certified(a: FloatArray, b: FloatArray, k: int) -> _Solved:
    """Exact matching over a candidate graph grown until the dual check over all N^2 edges
    passes (module docstring); a round cap or float trouble ends it unproven."""
    n = len(a)
    kk = min(k, n)
    edges, u, v = _first_graph(a, b, k)
    rounds = 0
    quantum = WEIGHT_QUANTUM
    failing, gap = np.arange(n), np.inf
    while rounds < MAX_ROUNDS:
        rounds += 1
        rows, cols = np.divmod(edges, n)
        cost = np.sum((a[rows] - b[cols]) ** 2, axis=1)
        # the last round's reduced costs have the same optimum (every full matching's cost
        # shifts by sum u + sum v) and make its matching all but optimal: a warm start
        # (lapmod on the plain costs takes as long in every round as in the first); shifted
        # to >= 0, and to >= 1 in the matcher, as explicit zeros would be dropped
        reduced_cost = cost - u[rows] - v[cols]
        order, quantised = _match(rows, cols,
                                  reduced_cost - min(0.0, float(reduced_cost.min())), quantum, n)
        own = np.sum((a - b[order]) ** 2, axis=1)
        u = _potentials(order, rows, cols, cost, own, u)
        v = np.empty(n)
        v[order] = own - u
        if quantised and quantum > FINEST_QUANTUM \
                and float(np.min(cost - u[rows] - v[cols])) < -TOLERANCE:
            # optimal to the quantum but not on the exact costs of its own graph: finer
            quantum *= 1e-3
            continue
        best_cost, _ = _lifted_best(a, b, v, 1)
        # any v gives the dual bound sum_i min_j (cost[i, j] - v[j]) + sum_j v[j]
        gap = float(np.sum(own)) - float(np.sum(best_cost[:, 0]) + np.sum(v))
        failing = np.flatnonzero(best_cost[:, 0] - u < -TOLERANCE)
        if not len(failing):
            break
        # the failing starts' best goals at these prices join the graph
        best_cost, best = _lifted_best(a[failing], b, v, kk)
        improving = best_cost - u[failing, None] < -TOLERANCE
        added = np.unique(np.repeat(failing, best.shape[1])[improving.reshape(-1)] * n
                          + best[improving])
        new = added[edges[np.minimum(np.searchsorted(edges, added), len(edges) - 1)] != added]
        if not len(new):
            break
        edges = np.sort(np.concatenate([edges, new]))
    return _Solved(order, u, v, max(gap, 0.0), not len(failing), rounds, len(edges))


#: lapmod refuses costs from 1e6 on; graphs with larger weights go to scipy.
LAPMOD_MAX_COST = 1e5


@functools.cache
def matcher() -> str:
    """The exact sparse matcher `_match` uses: "lapmod" (the `lap` package's sparse
    Jonker-Volgenant, 2-3x faster on these graphs) when installed, else "scipy"."""
    try:
        import lap  # noqa: F401
    except ImportError:
        return "scipy"
    return "lapmod"


def _match(rows: IntArray, cols: IntArray, weight: FloatArray, quantum: float,
           n: int) -> tuple[IntArray, bool]:
    """order[i]: row i's column in a minimum-weight full matching over the edges (rows,
    cols) with weights >= 0 (sorted by row then column, one per pair; a full matching
    exists): lapmod on the weights themselves where it takes them, else scipy on them in
    whole `quantum`s (`WEIGHT_QUANTUM`: scipy stalls on float near-ties). Exact either way
    (to the quantum for scipy, which the second value says); the certificate does not trust
    it (`_certified`)."""
    if matcher() == "lapmod" and float(weight.max()) + 1.0 < LAPMOD_MAX_COST:
        import lap

        first = np.searchsorted(rows, np.arange(n + 1)).astype(np.int32)
        _, order, _ = lap.lapmod(n, np.ascontiguousarray(weight + 1.0, dtype=np.float64),
                                 first, cols.astype(np.int32))
        return np.asarray(order, dtype=np.intp), False
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    graph = csr_matrix((np.rint(weight / quantum) + 1.0, (rows, cols)), shape=(n, n))
    _, matched = min_weight_full_bipartite_matching(graph)
    return np.asarray(matched, dtype=np.intp), True


def _potentials(order: IntArray, rows: IntArray, cols: IntArray, cost: FloatArray,
                own: FloatArray, start: FloatArray) -> FloatArray:
    """Start potentials u of an optimal matching over the candidate edges: u[i] + v[j] <=
    cost on every edge with v[order[i]] = own[i] - u[i]. Those are difference constraints
    u[i] <= u[i'] + cost[i, order[i']] - own[i'], solved as shortest paths from a virtual
    source (Bellman-Ford, vectorised over the edges leaving the starts that moved last round;
    an optimal matching leaves no negative cycle). Relaxing from `start` (the last round's
    potentials) gives the largest solution below it, in few passes when little changed."""
    n = len(order)
    owner = np.empty(n, dtype=np.intp)
    owner[order] = np.arange(n)
    tail = owner[cols]
    keep = tail != rows
    tail, head, weight = tail[keep], rows[keep], cost[keep] - own[tail[keep]]
    by_tail = np.argsort(tail, kind="stable")
    tail, head, weight = tail[by_tail], head[by_tail], weight[by_tail]
    first = np.searchsorted(tail, np.arange(n + 1))
    u = start.copy()
    frontier = np.arange(n)
    slack = TOLERANCE * 1e-3
    for _ in range(n + 1):
        counts = first[frontier + 1] - first[frontier]
        total = int(counts.sum())
        if total == 0:
            break
        # the edges leaving the frontier, gathered from their CSR rows
        edge = np.repeat(first[frontier] - np.cumsum(counts) + counts, counts) + np.arange(total)
        best = np.full(n, np.inf)
        np.minimum.at(best, head[edge], u[tail[edge]] + weight[edge])
        frontier = np.flatnonzero(best < u - slack)
        u[frontier] = best[frontier]
    return u


def certify(starts: FloatArray, goals: FloatArray, order: IntArray,
            scale: FloatArray | None = None, neighbours: int = NEIGHBOURS) -> bool:
    """Is `order` (order[n]: the goal of start n) proven optimal? Potentials tight on its
    edges are derived over its edges and each point's nearest others (`_potentials`) and
    checked against all N^2 edges (`_lifted_best`, nothing N x N); edges that fail join and
    the potentials are redone. Such potentials exist only for an optimal order
    (complementary slackness), so a worse order is always rejected; an optimal one is
    accepted unless `MAX_ROUNDS` rounds do not settle it."""
    from scipy.spatial import cKDTree

    s = np.ones(np.shape(starts)[1]) if scale is None else np.asarray(scale, dtype=float)
    a, _ = _normalised(np.asarray(starts, dtype=float) / s)
    b, _ = _normalised(np.asarray(goals, dtype=float) / s)
    order = np.asarray(order, dtype=np.intp)
    n = len(a)
    if sorted(order.tolist()) != list(range(n)):
        raise ValueError("order must be a permutation of the goals")
    if n < 2:
        return True
    kk = min(neighbours, n)
    _, near_goals = cKDTree(b).query(a, kk)
    _, near_starts = cKDTree(a).query(b, kk)
    everyone = np.repeat(np.arange(n), kk)
    edges = np.unique(np.concatenate([np.arange(n) * n + order,
                                      everyone * n + np.asarray(near_goals).reshape(-1),
                                      np.asarray(near_starts).reshape(-1) * n + everyone]))
    own = np.sum((a - b[order]) ** 2, axis=1)
    u = np.zeros(n)
    for _ in range(MAX_ROUNDS):
        rows, cols = np.divmod(edges, n)
        cost = np.sum((a[rows] - b[cols]) ** 2, axis=1)
        u = _potentials(order, rows, cols, cost, own, u)
        v = np.empty(n)
        v[order] = own - u
        if np.any(cost - u[rows] - v[cols] < -TOLERANCE):
            return False  # no tight potentials even on these edges: an improving cycle
        best_cost, best = _lifted_best(a, b, v, kk)
        failing = best_cost - u[:, None] < -TOLERANCE
        if not failing.any():
            return True
        # an edge cheaper than the potentials allow joins, and the potentials are redone
        added = np.repeat(np.arange(n), best.shape[1])[failing.reshape(-1)] * n + best[failing]
        edges = np.union1d(edges, added)
    return False


def capt_spacing_holds(starts: FloatArray, goals: FloatArray, separation: float,
                       scale: FloatArray | None = None) -> bool:
    """Are starts and goals each at least sqrt(2) R apart (separation metric)? Each point's
    nearest other point comes from a k-d tree: no all-pairs array at show scale."""
    from scipy.spatial import cKDTree

    s = np.ones(3) if scale is None else np.asarray(scale, dtype=float)
    need = CAPT_SPACING * separation
    for points in (starts / s, goals / s):
        if len(points) > 1 and float(cKDTree(points).query(points, 2)[0][:, 1].min()) < need:
            return False
    return True
