"""Closed-form IK of a robot that holds the C (mount joints, :mod:`carmkin.model.mount_joints`), vectorised.

The robots that carry a C-arm (a KUKA KR 210 class arm: the ``robotic-carm`` preset) are six revolute axes
whose last three meet in one point, the **wrist centre** c, and whose second and third are parallel. Their
inverse kinematics is Pieper's: the wrist centre's position gives axes 1–3, the orientation axes 4–6. With
the twists at rest (``η_i``: unit axis ``ω_i`` through the point ``p_i``, frame 0) and the motion wanted
``G = e^{η1 q1} ··· e^{η6 q6}`` (4, 4), each step is one of the Paden–Kahan subproblems. Nothing refers to
a zero of the angles but the twists at rest: a robot stated at its data sheet's zero (a KR 210's arm stretched
out) or at a rest pose within its ranges (the ``robotic-carm`` preset: the elbow folded up, each range the data
sheet's less the rest angle) is solved alike, its angles offset by the rest pose.

1. **q1**: rotations about the parallel axes 2 and 3 keep ``ω2·x``; so ``e^{-η1 q1}`` must bring the target
   wrist centre ``w = G c`` into the plane ``ω2·x = ω2·c``: ``A cos q1 + B sin q1 = C`` — two roots
   (the shoulder in front of or behind axis 1);
2. **q3**: a rotation about axis 2 keeps the distance to its point ``p2``: ``|e^{η3 q3} c − p2| = |w' − p2|``
   with ``w' = e^{-η1 q1} w`` (subproblem 3: again ``A cos + B sin = C``, two roots, elbow up or down);
3. **q2**: the rotation about axis 2 that takes ``e^{η3 q3} c`` to ``w'`` (subproblem 1);
4. **q4, q5**: the wrist rotation ``R_w = (R1 R2 R3)ᵀ R_G`` about c must turn ``ω6`` to ``R_w ω6``; two
   rotations about the intersecting axes 4 and 5 do it in two ways (subproblem 2, the wrist flipped or not);
5. **q6**: what ``R4 R5`` leaves of ``R_w``, about ``ω6`` (subproblem 1).

So 2 × 2 × 2 = 8 **branches** (index ``4·shoulder + 2·elbow + wrist``); a branch exists where its roots are
real and the forward kinematics of its joints gives G back to :data:`RESIDUAL_TOLERANCE`. At a wrist
singularity (axes 4 and 6 in line) q4 keeps the reference value and q6 takes the rest; at a shoulder
singularity (the wrist centre on axis 1) q1 does. Near a double root (close to those singularities, or at the
edge of the arm's reach, where a discriminant short of 0 by its round-off, :data:`ROOT_ROUNDOFF`, is a double
root) a square root turns round-off ε into √ε: a branch whose residual exceeds :data:`POLISH_ABOVE` takes two
Gauss–Newton steps on the twists (quadratic: ~1e-8 becomes round-off). Every angle is then written as the
representative ``q + 2πk`` within the joint's range (:data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE`) nearest the
reference — a KR 210's axes 4 and 6 turn ±350° — or marked out of range.

:func:`solve` is the IK of one source pose with the robot's six joints free and every other joint held;
:func:`branches` the same for many poses at once (the view search of :mod:`carmkin.views.mount` calls it with
a few thousand poses a map). A mount of another structure is refused with an
:class:`~carmkin.errors.UnsupportedMountError` naming what differs (the QP, :func:`carmkin.qp_ik.solve`,
solves it). Lengths in m, angles in rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import InvalidConfigurationError, UnsupportedMountError
from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.model.per_system import per_system

#: Axes meet, are parallel or perpendicular to this (m, or the sine of an angle): the structure test.
STRUCTURE_TOLERANCE = 1e-9
#: A branch reaches the pose when the forward kinematics of its joints gives the motion back to this (m and
#: rad): far above the closed form's round-off (~1e-15), far below any joint step that matters.
RESIDUAL_TOLERANCE = 1e-9
#: Below this, ``A cos q + B sin q = C`` leaves q free (|(A, B)|, m) and a subproblem's vector has no
#: direction (m or dimensionless): the angle keeps its reference value.
DEGENERATE = 1e-12
#: A branch whose residual (m + rad) exceeds this after the closed form — near a double root, where a square
#: root turns the round-off ε into √ε — takes :data:`POLISH_STEPS` Newton steps from there (each squares the error).
POLISH_ABOVE = 1e-14
POLISH_STEPS = 2
#: Relative round-off (dimensionless, 64 ulp) of the terms summed into a subproblem's ``A cos q + B sin q = C``
#: (and of the wrist's ``γ²``): a discriminant above minus this many times the size of those terms is a double
#: root reached within round-off (the arm stretched out or folded back at the edge of its reach, wherever the
#: rest pose puts it), kept at its double value; the residual check then decides whether the branch exists.
ROOT_ROUNDOFF = 64 * float(np.finfo(float).eps)
#: Number of branches: shoulder × elbow × wrist.
BRANCHES = 8


@dataclass(frozen=True)
class MountIK:
    """The solver of one mount: axes ``omega`` (6, 3) and points ``points`` (6, 3) in frame 0 at rest, the
    wrist centre ``wrist`` (3,), the mount joints' ranges ``lower``/``upper`` (6,) (rad), and where the
    mount joints sit in q (``start``: q[start:start + 6])."""

    omega: np.ndarray
    points: np.ndarray
    wrist: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    start: int


def _refuse(why: str):
    raise UnsupportedMountError(f"the mount's closed form needs six revolute joints whose last three axes meet in "
                                f"one point and whose second and third are parallel: {why}")


@per_system
def solver_for(system) -> MountIK:
    """The :class:`MountIK` of ``system`` (built once per system), or an
    :class:`~carmkin.errors.UnsupportedMountError` naming what its mount lacks."""
    from carmkin.model.system import require_system

    require_system(system, UnsupportedMountError)
    joints = system.mount.twists
    if len(joints) != 6:
        _refuse(f"this system has {len(joints)} mount joint(s)")
    for joint in joints:
        if joint.prismatic:
            _refuse(f"{joint.name} is prismatic")
    w = np.array([j.axis for j in joints], dtype=float)
    p = np.array([j.point for j in joints], dtype=float)
    if np.linalg.norm(np.cross(w[1], w[2])) > STRUCTURE_TOLERANCE:
        _refuse(f"the axes of {joints[1].name} and {joints[2].name} are not parallel")
    if np.linalg.norm(np.cross(w[0], w[1])) < 1e-6:
        _refuse(f"the axes of {joints[0].name} and {joints[1].name} are parallel")
    if np.linalg.norm(np.cross(w[3], w[4])) < 1e-6 or np.linalg.norm(np.cross(w[4], w[5])) < 1e-6:
        _refuse(f"two neighbouring wrist axes ({joints[3].name}, {joints[4].name}, {joints[5].name}) are parallel")
    # the wrist centre: the point of axis 4 nearest axis 5, then on all three axes
    n = np.cross(w[3], w[4])
    d = p[4] - p[3]
    t = np.dot(np.cross(d, w[4]), n) / np.dot(n, n)
    c = p[3] + t * w[3]
    for k in (3, 4, 5):
        off = np.linalg.norm(np.cross(c - p[k], w[k]))
        if off > STRUCTURE_TOLERANCE:
            _refuse(f"the wrist axes do not meet in one point ({joints[k].name} passes {off * 1e3:.3g} mm from the "
                    "others' crossing)")
    k = 1 + len(system.table.joints)
    return MountIK(w, p, c, system.lower[k:k + 6].copy(), system.upper[k:k + 6].copy(), k)


def _rotations(omega, theta):
    """Rotations (..., 3, 3) by ``theta`` (...) about the unit axis ``omega`` (3,) (Rodrigues)."""
    K = np.array([[0.0, -omega[2], omega[1]], [omega[2], 0.0, -omega[0]], [-omega[1], omega[0], 0.0]])
    s, v = np.sin(theta)[..., None, None], (1.0 - np.cos(theta))[..., None, None]
    return np.eye(3) + s * K + v * (K @ K)


def _cos_sin_roots(A, B, C, reference, size):
    """The two q of ``A cos q + B sin q = C`` (..., 2): NaN where there is none, ``reference`` (twice) where
    (A, B) vanishes and C does too (q free). ``size`` (...) the size of the terms summed into A, B and C (the
    unit of C): a discriminant ``A² + B² − C²`` short of 0 by less than their round-off
    (:data:`ROOT_ROUNDOFF`) is a double root."""
    r2 = A * A + B * B
    disc = r2 - C * C
    # a double root reached within round-off: keep it (the residual check decides); near it |C| ≈ |(A, B)|, so
    # the round-off of C² is that of C (relative to size) times 2 |(A, B)|
    tol = ROOT_ROUNDOFF * (r2 + 2.0 * np.sqrt(r2) * size)
    disc = np.where((disc < 0) & (disc > -tol), 0.0, disc)
    with np.errstate(invalid="ignore"):
        half = np.arctan2(np.sqrt(disc), C)
    phi = np.arctan2(B, A)
    roots = np.stack((phi + half, phi - half), axis=-1)
    free = np.sqrt(r2) < DEGENERATE
    roots = np.where(free[..., None], np.where((np.abs(C) < DEGENERATE)[..., None], reference[..., None], np.nan),
                     roots)
    return roots


def _angle_about(omega, u, v, reference):
    """The rotation angle (...) about the unit ``omega`` (3,) taking the direction of ``u`` (..., 3) to that of
    ``v`` (..., 3) (subproblem 1 on their parts ⊥ omega); ``reference`` where either part vanishes."""
    u = u - (u @ omega)[..., None] * omega
    v = v - (v @ omega)[..., None] * omega
    angle = np.arctan2(np.cross(u, v) @ omega, np.einsum("...i,...i->...", u, v))
    small = (np.linalg.norm(u, axis=-1) < DEGENERATE) | (np.linalg.norm(v, axis=-1) < DEGENERATE)
    return np.where(small, reference, angle)


def raw_branches(ik: MountIK, G, reference):
    """The eight branches (N, 8, 6) of motions ``G`` (N, 4, 4), angles in (−π, π] (NaN where a root is not
    real), and each branch's residual (N, 8) (m + rad: ``|Δc| + |Δθ|``, the wrist centre that joints 1–3 give
    against the target's and the rotation of the six joints against G's: the whole motion, since joints 4–6
    turn about the wrist centre; inf where NaN). ``reference`` (N, 6): the values a free angle keeps."""
    w, p, c = ik.omega, ik.points, ik.wrist
    N = len(G)
    R, t = G[:, :3, :3], G[:, :3, 3]
    target = R @ c + t  # the wrist centre after the motion (N, 3)
    # 1. q1: (R1(q1) ω2)·(x − p1) = ω2·(c − p1) with x the target wrist centre
    u = w[1]
    u_par = (u @ w[0]) * w[0]
    u_perp = u - u_par
    v = target - p[0]
    A = v @ u_perp
    B = v @ np.cross(w[0], u_perp)
    C = u @ (c - p[0]) - (u @ w[0]) * (v @ w[0])
    # the size of the coordinates (m) the terms are computed from: the target's, the points' (frame 0)
    coordinates = np.linalg.norm(target, axis=-1) + np.linalg.norm(c) + np.linalg.norm(p[0]) + np.linalg.norm(p[1])
    q1 = _cos_sin_roots(A, B, C, reference[:, 0], coordinates)  # (N, 2)
    R1 = _rotations(w[0], q1)  # (N, 2, 3, 3)
    # the target wrist centre seen before joint 1: e^{-η1 q1} x
    moved = np.einsum("nkji,nj->nki", R1, v) + p[0]  # R1ᵀ (x − p1) + p1, (N, 2, 3)
    # 2. q3: |e^{η3 q3} c − p2| = |moved − p2|
    a = c - p[2]
    e = p[1] - p[2]
    a_perp = a - (a @ w[2]) * w[2]
    delta2 = np.sum((moved - p[1]) ** 2, axis=-1)  # (N, 2)
    A3 = np.full_like(delta2, a_perp @ e)
    B3 = np.full_like(delta2, np.cross(w[2], a_perp) @ e)
    C3 = 0.5 * (a @ a + e @ e - delta2) - (w[2] @ a) * (w[2] @ e)
    # C3's terms: |a|², |e|², δ², and δ²'s round-off: 2 δ times that of the coordinates it is measured between
    size3 = a @ a + e @ e + delta2 + 2.0 * np.sqrt(delta2) * coordinates[:, None]
    q3 = _cos_sin_roots(A3, B3, C3, np.repeat(reference[:, 2:3], 2, axis=1), size3)  # (N, 2, 2): shoulder, elbow
    R3 = _rotations(w[2], q3)  # (N, 2, 2, 3, 3)
    x = R3 @ a + p[2]  # e^{η3 q3} c, (N, 2, 2, 3)
    # 3. q2: about axis 2, x to moved
    q2 = _angle_about(w[1], x - p[1], moved[:, :, None, :] - p[1], reference[:, None, None, 1])
    R2 = _rotations(w[1], q2)
    # axes 2 and 3 parallel (or opposed: σ = ω2·ω3 = ±1): R2 R3 is one rotation about ω2 by q2 + σ q3
    R123 = R1[:, :, None] @ _rotations(w[1], q2 + (w[1] @ w[2]) * q3)  # (N, 2, 2, 3, 3)
    Rw = np.swapaxes(R123, -1, -2) @ R[:, None, None]  # the wrist's rotation
    # 4. q4, q5: R4 R5 ω6 = Rw ω6 (subproblem 2)
    goal = Rw @ w[5]  # (N, 2, 2, 3)
    k = w[3] @ w[4]
    n = np.cross(w[3], w[4])
    g4, w56 = goal @ w[3], w[4] @ w[5]
    alpha = (k * w56 - g4) / (k * k - 1.0)
    beta = (k * g4 - w56) / (k * k - 1.0)
    if abs(k) <= STRUCTURE_TOLERANCE:  # axes 4 ⊥ 5 (a KR 210's): 1 − α² = |ω4 × goal|², no cancellation near α = ±1
        gamma2 = (np.sum(np.cross(goal, w[3]) ** 2, axis=-1) - beta ** 2) / (n @ n)
    else:
        gamma2 = (1.0 - alpha ** 2 - beta ** 2 - 2.0 * alpha * beta * k) / (n @ n)
    gamma2 = np.where((gamma2 < 0) & (gamma2 > -ROOT_ROUNDOFF), 0.0, gamma2)  # of unit vectors: size 1
    with np.errstate(invalid="ignore"):
        gamma = np.sqrt(gamma2)[..., None] * np.array([1.0, -1.0])  # (N, 2, 2, 2)
    z = alpha[..., None, None] * w[3] + beta[..., None, None] * w[4] + gamma[..., None] * n  # (N, 2, 2, 2, 3)
    ref = reference[:, None, None, None]
    q5 = _angle_about(w[4], np.broadcast_to(w[5], z.shape), z, ref[..., 4])
    q4 = _angle_about(w[3], z, np.broadcast_to(goal[..., None, :], z.shape), ref[..., 3])
    R45 = _rotations(w[3], q4) @ _rotations(w[4], q5)
    R6 = np.swapaxes(R45, -1, -2) @ Rw[:, :, :, None]
    # 5. q6: about axis 6, a direction ⊥ ω6 to where R6 turns it
    helper = np.eye(3)[int(np.argmin(np.abs(w[5])))]
    m = np.cross(w[5], helper)
    m /= np.linalg.norm(m)
    q6 = _angle_about(w[5], np.broadcast_to(m, z.shape), R6 @ m, ref[..., 5])
    q = np.stack(np.broadcast_arrays(q1[:, :, None, None], q2[..., None], q3[..., None], q4, q5, q6), axis=-1)
    # the residual of each branch: its wrist centre (joints 1-3) against the target's, its rotation against G's
    centre = np.einsum("nkij,nkej->nkei", R1, np.einsum("nkeij,nkej->nkei", R2, x - p[1]) + p[1] - p[0]) + p[0]
    dp = np.linalg.norm(centre - target[:, None, None], axis=-1)[..., None]  # (N, 2, 2, 1)
    D = np.swapaxes(_rotations(w[5], q6), -1, -2) @ R6
    cos = np.clip(0.5 * (D[..., 0, 0] + D[..., 1, 1] + D[..., 2, 2] - 1.0), -1.0, 1.0)
    sin = 0.5 * np.sqrt((D[..., 2, 1] - D[..., 1, 2]) ** 2 + (D[..., 0, 2] - D[..., 2, 0]) ** 2
                        + (D[..., 1, 0] - D[..., 0, 1]) ** 2)
    res = (dp + np.arctan2(sin, cos)).reshape(N, BRANCHES)
    q = q.reshape(N, BRANCHES, 6)
    res = np.where(np.isfinite(res) & np.isfinite(q).all(axis=-1), res, np.inf)
    rough = np.nonzero((res > POLISH_ABOVE) & np.isfinite(res))
    if len(rough[0]):  # near a double root (a wrist or arm singularity, the edge of reach): Newton's steps
        q[rough], res[rough] = _polish(ik, G[rough[0]], q[rough])
    q = np.arctan2(np.sin(q), np.cos(q))  # (−π, π]
    return q, res


def _fk(ik: MountIK, q) -> np.ndarray:
    """``e^{η1 q1} ··· e^{η6 q6}`` (M, 4, 4) and the spatial twists (M, 6, 6) (columns ``(v, ω)`` of each
    joint at q) for q (M, 6)."""
    M = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    J = np.empty((len(q), 6, 6))
    for i in range(6):
        w = M[:, :3, :3] @ ik.omega[i]
        point = M[:, :3, :3] @ ik.points[i] + M[:, :3, 3]
        J[:, 3:, i], J[:, :3, i] = w, -np.cross(w, point)
        Ri = _rotations(ik.omega[i], q[:, i])
        step = np.zeros((len(q), 4, 4))
        step[:, :3, :3] = Ri
        step[:, :3, 3] = ik.points[i] - Ri @ ik.points[i]
        step[:, 3, 3] = 1.0
        M = M @ step
    return M, J


def _twist_error(M, G):
    """The spatial twist ``(v, ω)`` (M, 6) with ``G ≈ exp([ξ]) M`` and its size ``|v| + |ω|`` (M,)."""
    D = G[:, :3, :3] @ np.swapaxes(M[:, :3, :3], -1, -2)
    cos = np.clip(0.5 * (np.trace(D, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    axis = 0.5 * np.stack((D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0], D[:, 1, 0] - D[:, 0, 1]), axis=-1)
    sin = np.linalg.norm(axis, axis=-1)
    angle = np.arctan2(sin, cos)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(sin[:, None] > 0, axis * (angle / sin)[:, None], 0.0)
    v = G[:, :3, 3] - M[:, :3, 3] - np.cross(w, M[:, :3, 3])
    return np.concatenate((v, w), axis=1), np.linalg.norm(G[:, :3, 3] - M[:, :3, 3], axis=1) + angle


def _polish(ik: MountIK, G, q):
    """:data:`POLISH_STEPS` Gauss–Newton steps (least squares: a singular Jacobian's free combination left at
    its least norm) of joints q (M, 6) towards motions G (M, 4, 4); ``(q, residual)``, the residual
    ``|Δp| + |Δθ|`` of the forward kinematics."""
    for _ in range(POLISH_STEPS):
        M, J = _fk(ik, q)
        xi, _ = _twist_error(M, G)
        q = q + (np.linalg.pinv(J, rcond=1e-10) @ xi[..., None])[..., 0]
    M, _ = _fk(ik, q)
    return q, _twist_error(M, G)[1]


def in_range(ik: MountIK, q, reference):
    """``(values, inside)``: each angle of q (N, B, 6) as its representative ``q + 2πk`` within the joint's
    range nearest ``reference`` (N, 6) (the principal value where none is), and whether every joint of a
    branch has one (N, B)."""
    tol = JOINT_RANGE_TOLERANCE
    shifts = q[..., None] + 2.0 * np.pi * np.array([-1.0, 0.0, 1.0])  # (N, B, 6, 3)
    lo, hi = ik.lower[:, None] - tol, ik.upper[:, None] + tol
    ok = (shifts >= lo) & (shifts <= hi)
    gap = np.where(ok, np.abs(shifts - reference[:, None, :, None]), np.inf)
    pick = np.argmin(gap, axis=-1)
    values = np.take_along_axis(shifts, pick[..., None], axis=-1)[..., 0]
    joint_ok = ok.any(axis=-1)
    return np.where(joint_ok, values, q), joint_ok.all(axis=-1) & np.isfinite(q).all(axis=-1)


def _held_parts(system, q_hold):
    """``(before, after)`` (N, 4, 4): what the held joints of q_hold (N, nq) put before the mount's motion
    (``Tz(d0) E(q_table)``) and after it (the C-arm's chain ``P(q6 with d0 = 0)``)."""
    k = 1 + len(system.table.joints)
    rest = q_hold.copy()
    rest[:, k:k + 6] = 0.0
    before = system.base_motion(rest)
    q6 = system.split(q_hold)[0].copy()
    q6[:, 0] = 0.0
    return before, system.closed_form.poses(q6)


@dataclass(frozen=True)
class Branches:
    """Per pose (N) and branch (8): ``q`` (N, 8, nq) the full configuration (the held joints as given, the mount
    joints' values in range where they can be: see :func:`in_range`; NaN where the branch does not exist),
    ``reachable`` (N, 8) the branch exists (its forward kinematics gives the pose back to
    :data:`RESIDUAL_TOLERANCE`), ``within_limits`` (N, 8) and it is within every joint's range."""

    q: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray


def branches(system, T, q_hold) -> Branches:
    """The eight closed-form branches of source poses ``T`` (N, 4, 4) (table frame) with the mount's joints free
    and the others held at ``q_hold`` (N, nq) (m, rad; the mount joints' values of q_hold are the reference
    of the angle representatives and of free angles). No checks of T or q_hold: the callers' (:func:`solve`
    checks; the view search builds them)."""
    ik = solver_for(system)
    before, after = _held_parts(system, q_hold)
    G = np.linalg.inv(before) @ T @ np.linalg.inv(after)
    reference = q_hold[:, ik.start:ik.start + 6]
    with np.errstate(invalid="ignore"):
        q, res = raw_branches(ik, G, reference)
        values, inside = in_range(ik, q, reference)
    reachable = res <= RESIDUAL_TOLERANCE
    full = np.repeat(q_hold[:, None, :], BRANCHES, axis=1)
    full[..., ik.start:ik.start + 6] = values
    full[~reachable] = np.nan
    return Branches(full, reachable, reachable & inside)


@dataclass(frozen=True)
class MountIKResult:
    """The IK of one source pose: ``solutions`` (8, nq) every branch's configuration (NaN where it does not
    exist), ``reachable`` (8,) and ``within_limits`` (8,) per branch (see :class:`Branches`), ``clearance``
    (8,) the exact clearance (m) of each branch within limits when a world was given (NaN otherwise),
    ``chosen`` the branch within limits (and clear of the margin, with a world) nearest ``q_current``
    (normalised by the joint spans), or None, and ``reason`` when there is none."""

    solutions: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray
    chosen: int | None
    reason: str | None
    clearance: np.ndarray | None = None

    @property
    def success(self) -> bool:
        return self.chosen is not None

    @property
    def q(self) -> np.ndarray | None:
        """The chosen configuration (nq,), or None."""
        return None if self.chosen is None else self.solutions[self.chosen]


def solve(system, T, q_current=None, *, world=None, margin: float = 0.0) -> MountIKResult:
    """Every closed-form solution of the source pose ``T`` (4, 4) (``xray_source`` in the table frame) with the
    robot's six joints free and the other joints held at ``q_current`` (nq,) (default: the middle of the
    ranges), and the one within limits nearest it. With ``world`` (a :class:`carmkin.world.World` of this
    system, e.g. with the patient), the branches within limits are checked at once by its exact clearance and
    the one chosen is the nearest that keeps ``margin`` (m; e.g. ``carmkin.DEFAULT_MARGIN``). A pose out of
    reach (or every branch in contact) is a result without a solution (its ``reason`` says why), never an
    exception; a malformed T, q_current, world or margin, a system without such a mount, are typed errors
    naming the argument."""
    from carmkin.transforms import check_rigid_transform
    from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar

    ik = solver_for(system)
    T = check_rigid_transform(T, "T")
    if q_current is None:
        q_ref = 0.5 * (system.lower + system.upper)
    else:
        q_ref = real_array(q_current, "q_current", (system.nq,), error=InvalidConfigurationError,
                           limit=JOINT_VALUE_LIMIT, unit="m, rad")
    margin = real_scalar(margin, "margin", error=InvalidConfigurationError, low=0.0, high=1.0, unit="m")
    if world is not None and (not callable(getattr(world, "clearance", None))
                              or getattr(world, "system", None) != system):
        raise InvalidConfigurationError(f"world must be a carmkin.world.World of this system (World(system, "
                                        f"patient)), got {type(world).__name__}")
    out = branches(system, T[None], q_ref[None])
    q, reachable, within = out.q[0], out.reachable[0], out.within_limits[0]
    clearance, allowed = None, within
    if world is not None:
        clearance = np.full(BRANCHES, np.nan)
        if within.any():
            clearance[within] = world.clearance(q[within])
        allowed = within & (np.nan_to_num(clearance, nan=-np.inf) >= margin)
    chosen, reason = None, None
    if allowed.any():
        span = np.maximum(system.upper - system.lower, 1e-9)
        cost = np.where(allowed, np.nansum(np.abs((q - q_ref) / span), axis=1), np.inf)
        chosen = int(np.argmin(cost))
    elif within.any():
        reason = (f"contact: each of the {int(within.sum())} branch(es) within the joint ranges comes within the "
                  f"margin ({margin * 1e3:.1f} mm; closest {np.nanmax(clearance) * 1e3:.1f} mm)")
    elif reachable.any():
        reason = (f"{int(reachable.sum())} branch(es) reach the pose, none within the mount's joint ranges "
                  f"({', '.join(j.name for j in system.mount.joints)})")
    else:
        reason = "out of reach: no branch of the robot's closed form gives the pose (the wrist centre beyond the arm)"
    return MountIKResult(q, reachable, within, chosen, reason, clearance)


__all__ = ["BRANCHES", "DEGENERATE", "RESIDUAL_TOLERANCE", "ROOT_ROUNDOFF", "STRUCTURE_TOLERANCE", "Branches",
           "MountIK", "MountIKResult", "branches", "in_range", "raw_branches", "solve", "solver_for"]
