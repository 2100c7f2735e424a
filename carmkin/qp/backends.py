"""QP backends of the IK: one object per solve call chain, reused for every step and every seed.

``solve(H, g, G, h, lb, ub)`` minimises ``½ dq^T H dq + g^T dq`` subject to ``G dq <= h`` and
``lb <= dq <= ub`` and returns ``dq`` or ``None`` when the QP is infeasible or the solver fails.
"""

from __future__ import annotations

import numpy as np
import qpsolvers
import scipy.sparse as sp

from .options import QPIKError

#: Backends in order of preference, fastest first as measured by ``benchmarks/bench_qp_ik.py`` (all reliable
#: there); ``None`` as backend means the first one installed. osqp is a core dependency, the others come
#: with the ``solvers`` extra.
BACKENDS = ("daqp", "quadprog", "proxqp", "osqp")
#: OSQP steps may leave the bounds by its tolerance; a larger violation (m or rad) counts as a failure.
OSQP_BOUND_SLACK = 1e-7


def default_backend() -> str:
    """The first installed backend of :data:`BACKENDS`."""
    for name in BACKENDS:
        if name in qpsolvers.available_solvers:
            return name
    raise QPIKError(f"none of the QP backends {BACKENDS} is installed")


class QpsolversBackend:
    """A QP solver through :func:`qpsolvers.solve_qp` (daqp, quadprog, proxqp, ...); these dense active-set
    solvers keep no workspace worth reusing (their setup is a few µs)."""

    def __init__(self, name: str, nv: int, max_rows: int) -> None:
        if name not in qpsolvers.available_solvers:
            raise QPIKError(f"QP backend {name!r} is not installed; available: {sorted(qpsolvers.available_solvers)}")
        self.name = name
        self.nv, self.max_rows = nv, max_rows
        self.options = {"eps_abs": 1e-12, "eps_rel": 0.0} if name == "proxqp" else {}

    def solve(self, H, g, G, h, lb, ub) -> np.ndarray | None:
        if G is not None and G.shape[0] == 0:
            G = h = None
        return qpsolvers.solve_qp(H, g, G, h, lb=lb, ub=ub, solver=self.name, **self.options)


class OSQPBackend:
    """OSQP with one persistent workspace: fixed sparsity, ``update()`` + ``solve()`` with warm start.

    Constraint matrix ``[I; G_pad]`` with ``max_rows`` dense rows of which unused ones get infinite bounds.
    Tolerances 1e-10 give steps exact enough for 1e-6 convergence; a step may leave the bounds by
    :data:`OSQP_BOUND_SLACK` only, and is projected back (a larger violation is a failure).
    """

    name = "osqp"
    SETTINGS = dict(eps_abs=1e-10, eps_rel=1e-10, polishing=False, max_iter=20000, verbose=False, warm_starting=True)

    def __init__(self, name: str, nv: int, max_rows: int) -> None:
        import osqp

        self.nv, self.max_rows = nv, max_rows
        P = sp.csc_matrix(np.triu(np.ones((nv, nv))))
        self._p_rows = P.indices.copy()
        self._p_cols = np.repeat(np.arange(nv), np.diff(P.indptr))
        A = sp.csc_matrix(np.ones((nv + max_rows, nv)))
        self._G = np.zeros((max_rows, nv))
        self._l = np.full(nv + max_rows, -np.inf)
        self._u = np.full(nv + max_rows, np.inf)
        A.data[:] = self._a_data()
        self.solver = osqp.OSQP()
        self.solver.setup(sp.csc_matrix((np.ones(P.nnz), P.indices, P.indptr), shape=(nv, nv)), np.zeros(nv), A,
                          self._l, self._u, **self.SETTINGS)

    def _a_data(self) -> np.ndarray:
        return np.vstack((np.eye(self.nv), self._G)).ravel(order="F")

    def solve(self, H, g, G, h, lb, ub) -> np.ndarray | None:
        m = 0 if G is None else G.shape[0]
        if m > self.max_rows:
            raise QPIKError(f"OSQP workspace holds {self.max_rows} inequality rows, got {m}")
        self._G[:] = 0.0
        self._l[:] = -np.inf
        self._u[:] = np.inf
        self._l[: self.nv], self._u[: self.nv] = lb, ub
        if m:
            self._G[:m] = G
            self._u[self.nv : self.nv + m] = h
        self.solver.update(q=g, l=self._l, u=self._u, Px=H[self._p_rows, self._p_cols], Ax=self._a_data())
        result = self.solver.solve(raise_error=False)
        if result.info.status_val != 1 or result.x is None or not np.all(np.isfinite(result.x)):
            return None
        x = result.x
        if np.any(x < lb - OSQP_BOUND_SLACK) or np.any(x > ub + OSQP_BOUND_SLACK):
            return None
        return np.clip(x, lb, ub)


class DAQPBackend:
    """DAQP called directly, with bound buffers allocated once: the same solver as ``qpsolvers`` with
    ``solver="daqp"``, without its per-call problem checks and copies (about half the cost of a step QP)."""

    name = "daqp"
    #: DAQP's stand-in for an infinite bound.
    INFINITY = 1e30

    def __init__(self, name: str, nv: int, max_rows: int) -> None:
        from ctypes import c_int

        import daqp

        self._solve = daqp.solve
        self.nv, self.max_rows = nv, max_rows
        self._upper = np.empty(nv + max_rows)
        self._lower = np.empty(nv + max_rows)
        self._sense = np.zeros(nv + max_rows, dtype=c_int)
        self._no_rows = np.zeros((0, nv))

    def solve(self, H, g, G, h, lb, ub) -> np.ndarray | None:
        m = 0 if G is None else G.shape[0]
        if m > self.max_rows:
            raise QPIKError(f"DAQP backend holds {self.max_rows} inequality rows, got {m}")
        n = self.nv
        upper, lower = self._upper[: n + m], self._lower[: n + m]
        upper[:n], lower[:n] = ub, lb
        if m:
            upper[n:] = h
            lower[n:] = -self.INFINITY
        x, _, exitflag, _ = self._solve(H, g, G if m else self._no_rows, upper, lower, self._sense[: n + m])
        if exitflag <= 0:
            return None
        return np.clip(x, lb, ub)  # DAQP meets bounds to its primal tolerance (~1e-7) only


def make_backend(name: str | None, nv: int, max_rows: int):
    """The backend ``name`` (``None`` = :func:`default_backend`) for ``nv`` variables and at most
    ``max_rows`` inequality rows."""
    name = default_backend() if name is None else name
    if name == "osqp":
        return OSQPBackend(name, nv, max_rows)
    if name == "daqp" and name in qpsolvers.available_solvers:
        return DAQPBackend(name, nv, max_rows)
    return QpsolversBackend(name, nv, max_rows)
