"""QP backends on the planner's real QPs: prints one JSON document to stdout.

    python bench/qp_solvers.py --grid-sphere 64 --random-dense --limit 6

Plans each case once with PIQP, keeping every group QP the SCP loop solved, then solves the
same QPs with each backend that is installed (PIQP, proxsuite's sparse ProxQP, QPALM, and
HPIPM through CasADi's conic interface) and reports per-backend total time, failures and the
largest objective difference to PIQP. Backends that are not installed are reported as such;
they are measured here, not dependencies of the planner (pip install proxsuite qpalm casadi
to measure them). DAQP (dense active set) is left out: the group QPs have 10^4-10^5 variables.
A backend is cut short after --budget seconds per case, but only between QPs: PIQP's
multistage KKT and ProxQP can take minutes on one large group QP.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

import planner  # noqa: E402
from planner.families.generators import grid_to_sphere, random_dense  # noqa: E402
from planner.scp import solvers  # noqa: E402
from planner.scp.qp import QuadraticProgram  # noqa: E402

BIG = 1e20


def capture(data: dict[str, Any]) -> list[QuadraticProgram]:
    """Every QP PIQP solves while planning `data`."""
    kept: list[QuadraticProgram] = []
    original = solvers.PiqpSolver.solve

    def recording(self: Any, qp: QuadraticProgram, warm_start: Any = None) -> Any:
        kept.append(qp)
        return original(self, qp, warm_start)

    solvers.PiqpSolver.solve = recording  # type: ignore[method-assign]
    try:
        planner.plan(data)
    finally:
        solvers.PiqpSolver.solve = original  # type: ignore[method-assign]
    return kept


def _stacked(qp: QuadraticProgram) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """Inequalities and variable bounds as one block l <= C x <= u (finite bounds only)."""
    bounded = np.flatnonzero(np.isfinite(qp.x_l) | np.isfinite(qp.x_u))
    eye = sp.identity(qp.size, format="csr")[bounded]
    c = sp.vstack([qp.G, eye], format="csc")
    lo = np.concatenate([qp.h_l, qp.x_l[bounded]])
    hi = np.concatenate([qp.h_u, qp.x_u[bounded]])
    return c, np.clip(lo, -BIG, BIG), np.clip(hi, -BIG, BIG)


def solve_piqp(qp: QuadraticProgram, kkt: str = "sparse_ldlt") -> tuple[bool, float]:
    result = solvers.PiqpSolver(kkt_solver=kkt).solve(qp)
    return result.status == solvers.SOLVED, result.objective


def solve_proxsuite(qp: QuadraticProgram) -> tuple[bool, float]:
    import proxsuite

    c, lo, hi = _stacked(qp)
    model = proxsuite.proxqp.sparse.QP(qp.size, qp.A.shape[0], c.shape[0])
    model.settings.eps_abs = 1e-8
    model.settings.eps_rel = 0.0
    model.settings.max_iter = 10_000
    model.init(qp.P, qp.q, qp.A, qp.b, c, lo, hi)
    model.solve()
    ok = model.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
    return ok, solvers._objective(qp, np.asarray(model.results.x))


def solve_qpalm(qp: QuadraticProgram) -> tuple[bool, float]:
    import qpalm

    c, lo, hi = _stacked(qp)
    a = sp.vstack([qp.A, c], format="csc")
    data = qpalm.Data(qp.size, a.shape[0])
    data.Q = sp.triu(qp.P, format="csc")
    data.q = qp.q
    data.A = a
    data.bmin = np.concatenate([qp.b, lo])
    data.bmax = np.concatenate([qp.b, hi])
    settings = qpalm.Settings()
    settings.eps_abs = 1e-8
    settings.eps_rel = 1e-9
    settings.max_iter = 10_000
    settings.verbose = False
    solver = qpalm.Solver(data, settings)
    solver.solve()
    ok = solver.info.status == "solved"
    return ok, solvers._objective(qp, np.asarray(solver.solution.x))


def solve_hpipm(qp: QuadraticProgram) -> tuple[bool, float]:
    """HPIPM through CasADi's conic interface, given the QP as one stage (no OCP structure
    detection: CasADi's hpipm plugin needs the stage dimensions spelled out, which the
    planner's stage ordering would allow but this measurement does not attempt)."""
    import casadi

    c, lo, hi = _stacked(qp)
    a = sp.vstack([qp.A, c], format="csc")
    h = casadi.DM(qp.P)
    am = casadi.DM(a)
    solver = casadi.conic("s", "hpipm", {"h": h.sparsity(), "a": am.sparsity()},
                          {"error_on_fail": False, "print_time": False})
    out = solver(h=h, g=qp.q, a=am, lba=np.concatenate([qp.b, lo]),
                 uba=np.concatenate([qp.b, hi]))
    ok = bool(solver.stats()["success"])
    return ok, solvers._objective(qp, np.asarray(out["x"]).ravel())


BACKENDS = {
    "piqp": solve_piqp,
    "piqp sparse_multistage": lambda qp: solve_piqp(qp, "sparse_multistage"),
    "piqp sparse_multistage_parallel": lambda qp: solve_piqp(qp, "sparse_multistage_parallel"),
    "piqp sparse_ldlt_cond": lambda qp: solve_piqp(qp, "sparse_ldlt_cond"),
    "qpalm": solve_qpalm,
    "proxsuite": solve_proxsuite,
    "hpipm (casadi)": solve_hpipm,
}


def compare(name: str, qps: list[QuadraticProgram], budget: float) -> dict[str, Any]:
    reference = []
    out: dict[str, Any] = {"case": name, "qps": len(qps),
                           "variables_max": max(q.size for q in qps),
                           "rows_max": max(q.A.shape[0] + q.G.shape[0] for q in qps)}
    for backend, solve in BACKENDS.items():
        began = time.perf_counter()
        failures, worst, solved = 0, 0.0, 0
        try:
            for n, qp in enumerate(qps):
                ok, objective = solve(qp)
                solved += 1
                if backend == "piqp":
                    reference.append(objective)
                elif not ok:
                    failures += 1
                else:
                    worst = max(worst, abs(objective - reference[n]) / abs(reference[n]))
                if time.perf_counter() - began > budget:
                    break
        except ImportError:
            out[backend] = {"installed": False}
            continue
        except RuntimeError as exc:  # e.g. CasADi's hpipm plugin rejecting the layout
            out[backend] = {"installed": True, "error": str(exc)[:300]}
            print(f"{name:>20} {backend:>16} error {str(exc)[:160]}", file=sys.stderr)
            continue
        seconds = time.perf_counter() - began
        out[backend] = {"installed": True, "solved_qps": solved, "seconds": round(seconds, 3),
                        "seconds_per_qp": round(seconds / max(solved, 1), 4),
                        "failures": failures, "objective_rel_diff_max": worst}
        print(f"{name:>20} {backend:>16} {solved} QPs {seconds:.2f} s failures {failures} "
              f"rel diff {worst:.2e}", file=sys.stderr, flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid-sphere", type=int, nargs="*", default=[64])
    parser.add_argument("--random-dense", type=int, nargs="*", default=[])
    parser.add_argument("--limit", type=int, default=6, help="QPs per case (largest first)")
    parser.add_argument("--budget", type=float, default=120.0,
                        help="seconds per backend and case before it is cut short")
    args = parser.parse_args()
    cases = [(f"grid-sphere{n}", grid_to_sphere(n)) for n in args.grid_sphere]
    cases += [(f"dense{n}", random_dense(n)) for n in args.random_dense]
    report = []
    for name, data in cases:
        qps = sorted(capture(data), key=lambda q: q.size, reverse=True)[:args.limit]
        report.append(compare(name, qps, args.budget))
    print(json.dumps({"benchmark": "qp_solvers", "cases": report}, indent=1))


if __name__ == "__main__":
    main()
