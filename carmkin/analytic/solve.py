"""The closed-form IK of the paper's 6-DOF chain for one pose: the solver built once per system, the
reference configuration read cheaply, regular and singular poses dispatched (§4.4.1–4.4.2).

:func:`carmkin.analytic_ik.solve` is this function behind the check of its ``system`` argument; the machinery
of this package (the single-axis table chain) calls it directly on the 6-DOF systems it builds.
"""

from __future__ import annotations

import math

from carmkin.analytic import singular
from carmkin.analytic.closed_form import SINGULAR_TOLERANCE, ClosedFormIK
from carmkin.analytic.poses import pose_rows
from carmkin.analytic.results import IKResult
from carmkin.errors import InvalidConfigurationError
from carmkin.model.kinematics import check_configuration
from carmkin.model.per_system import per_system
from carmkin.validation import JOINT_VALUE_LIMIT, plain_floats


#: The reference configuration when none is given.
ZERO = (0.0,) * 6


@per_system
def solver_for(system) -> ClosedFormIK:
    """The :class:`ClosedFormIK` of ``system``, built on first use and kept while the system lives
    (:func:`carmkin.model.per_system.per_system`; nothing is written into the frozen system)."""
    return ClosedFormIK(system)


def reference(q_current):
    """``q_current`` (6,) as a sequence of floats (m, rad), :data:`ZERO` when None; a plainly valid vector
    takes the fast path (:func:`carmkin.validation.plain_floats`)."""
    if q_current is None:
        return ZERO
    ref = plain_floats(q_current, 6, JOINT_VALUE_LIMIT)
    if ref is not None:
        return ref
    ref = check_configuration(q_current, 6, "q_current")
    if ref.ndim != 1:
        raise InvalidConfigurationError(f"q_current must be a finite vector of shape (6,), got {ref.shape}")
    return tuple(ref.tolist())


def solve_pose(system, T, q_current=None) -> IKResult:
    """Both closed-form solutions of ``T`` (4x4 pose of ``xray_source`` in the table frame) on a 6-DOF
    ``system`` already known to be a :class:`carmkin.CArmSystem`; see :func:`carmkin.analytic_ik.solve`."""
    T, rows, correction = pose_rows(T, "T")
    return solve_rows(system, T, rows, correction, q_current)


def solve_rows(system, T, rows, correction: float, q_current=None) -> IKResult:
    """:func:`solve_pose` of a pose already through :func:`~carmkin.analytic.poses.pose_rows`: ``T`` (4, 4)
    rigid, ``rows`` its nested lists, ``correction`` the projection it reported (the prepared IK checks its
    target once, not twice)."""
    ik = solver_for(system)
    q_ref = reference(q_current)
    q0, q1, det_j, _ = ik.angles_and_translations(rows)
    # singular: |det J| below SINGULAR_TOLERANCE (or NaN), or translations the closed form cannot give
    if not abs(det_j) >= SINGULAR_TOLERANCE or not math.isfinite(q0[0] + q1[0] + q0[3] + q1[3]):
        result = singular.solve(ik, T, rows, q_ref, q0, q1, det_j)
    else:
        result = ik.regular(T, q0, q1, det_j, q_ref)
    result.pose_correction = correction
    return result
