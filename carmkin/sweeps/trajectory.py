"""Joint trajectories of a sweep: the plain joint rotation and the compensated ("virtual isocentre") one.

A sweep turns the C-arm by an angle φ about one joint (``"orbital"``, ``"angular"``) or a combination of
revolute joints moving together (``{"orbital": 1.0, "angular": 0.2}``): the **plain** trajectory is
``q(φ) = q_ref + φ·w`` with ``w`` the joint weights (rad per rad of φ). Only for an isocentric C-arm whose
isocentre sits on the target does it keep the target on the principal axis; otherwise the target
**drifts** (a1, a2 ≠ 0, or a target away from the isocentre).

The **compensated** trajectory keeps the orientations of the plain one and moves the source so that the
target lies on the principal axis at the stated source-to-target distance ``d``: frame k is the pose
``[R_k | t − d·R_k e_z]`` (R_k from the plain trajectory, t the target), solved exactly per frame — by
:func:`carmkin.analytic_ik.solve_batch` on the paper's 6-joint chain (the orientation fixes θ2, θ4, θ5, the
prismatic joints follow linearly), by :func:`carmkin.qp_ik.solve` on any other system (its single-axis
closed form on a motorized table). For a single joint it is the rotation about the parallel axis through
the target. Frames: table frame 0; m and rad.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from carmkin.errors import SweepError
from carmkin.validation import real_scalar

#: Convergence (m, rad) of frames no closed form solves (the closed forms are exact): the target stays on the
#: principal axis to 1e-9 m on every system.
QP_TOLERANCE = 1e-10
#: Largest |weight| (rad of the joint per rad of φ) of a joint in a combined sweep.
MAX_WEIGHT = 10.0
#: Default sweep joint (the Siremobile Iso-C 3D acquires by orbital rotation, the preset's ±95°).
DEFAULT_JOINT = "orbital"


def joint_weights(system, joint) -> np.ndarray:
    """Weights ``w`` (nq,) of the revolute joints that turn with φ: a joint name (weight 1) or a mapping of
    names to weights (rad per rad). Prismatic or unknown joints are refused."""
    spec = {joint: 1.0} if isinstance(joint, str) else joint
    if not isinstance(spec, Mapping) or not spec:
        raise SweepError(f"joint must be a joint name or a mapping of joint names to weights, got {joint!r}")
    w = np.zeros(system.nq)
    for name, weight in spec.items():
        if not isinstance(name, str) or name not in system.joint_names:
            raise SweepError(f"joint {name!r} is not a joint of this system; joints: {', '.join(system.joint_names)}")
        k = system.joint_names.index(name)
        if system.prismatic[k]:
            raise SweepError(f"joint {name!r} is prismatic: a sweep turns revolute joints (e.g. orbital, angular)")
        value = real_scalar(weight, f"weight of joint {name!r}", error=SweepError, low=-MAX_WEIGHT, high=MAX_WEIGHT,
                            unit="rad/rad")
        if value == 0.0:
            raise SweepError(f"weight of joint {name!r} must be a non-zero number in [-10, 10] (rad/rad), got {weight!r}")
        w[k] = value
    return w


def frame_angles(arc: float, n_views: int, centred: bool) -> np.ndarray:
    """φ of the n frames (rad): evenly spaced over ``arc``, from −arc/2 when ``centred``, else from 0."""
    phi = np.linspace(0.0, arc, n_views)
    return phi - arc / 2.0 if centred else phi


def plain(q_ref: np.ndarray, w: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The plain joint trajectory ``q_ref + φ w`` (n, nq)."""
    return q_ref[None, :] + phi[:, None] * w[None, :]


def aligned_poses(R: np.ndarray, target: np.ndarray, distance: float) -> np.ndarray:
    """Source poses (n, 4, 4) with orientations ``R`` (n, 3, 3) and the target on the principal axis at
    ``distance`` from the source: ``p = t − d·R e_z``."""
    T = np.zeros((len(R), 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = target[None, :] - distance * R[:, :, 2]
    T[:, 3, 3] = 1.0
    return T


def solve_poses(system, T: np.ndarray, q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joints (n, nq) reaching the source poses ``T`` (n, 4, 4), branch nearest ``q_ref`` (n, nq), and
    whether each pose was reached (n,). Nothing is clipped: out-of-range values are left for the caller."""
    if system.nq == 6:
        from carmkin import analytic_ik

        result = analytic_ik.solve_batch(system, T, q_current=q_ref)
        index = np.arange(len(T))
        return result.q, result.reached[result.chosen, index] & np.all(np.isfinite(result.q), axis=1)
    from carmkin import qp_ik

    options = qp_ik.QPIKOptions(position_tolerance=QP_TOLERANCE, angle_tolerance=QP_TOLERANCE)
    q = np.full((len(T), system.nq), np.nan)
    reached = np.zeros(len(T), dtype=bool)
    # q_current is the branch reference and the held value of the table's other joints, which qp_ik wants in
    # range; a plain trajectory may run past a limit (that is reported by the caller, not here)
    q_current = np.clip(q_ref, system.lower, system.upper)
    for k in range(len(T)):
        # deterministic seeds only (closed-form branches, q_current, mid-range): a frame is near the previous one
        result = qp_ik.solve(system, T[k], q_current=q_current[k], accept=lambda report: True, random_seeds=0,
                             options=options)
        if result.success:  # an unconverged attempt is not a frame: NaN, reported as unreachable
            q[k] = result.q
            reached[k] = True
    return q, reached


def compensated(system, q_plain: np.ndarray, target: np.ndarray, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """The compensated trajectory (n, nq) of a plain one and the per-frame reached flags (n,)."""
    R = system.fk(q_plain, check_units=False)[:, :3, :3]
    return solve_poses(system, aligned_poses(R, target, distance), q_plain)


def target_errors(T: np.ndarray, target: np.ndarray, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """``(off_axis, along)`` (n,) m: the target's distance from the principal axis of each source pose
    ``T`` (n, 4, 4), and its depth along the axis minus ``distance``."""
    rel = target[None, :] - T[:, :3, 3]
    along = np.einsum("ni,ni->n", rel, T[:, :3, 2])
    off = np.linalg.norm(rel - along[:, None] * T[:, :3, 2], axis=1)
    return off, along - distance


def drift(T: np.ndarray, target: np.ndarray, distance: float) -> np.ndarray:
    """Isocentre drift (n,) m: distance from the target to the point at ``distance`` on the principal axis."""
    return np.linalg.norm(target[None, :] - T[:, :3, 3] - distance * T[:, :3, 2], axis=1)


def rotation_axis(system, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Unit axis (3,) of the instantaneous rotation of the source at ``q`` for joint rates ``w``, in the
    source frame (finite differences of the closed-form FK are avoided: Pinocchio's frame Jacobian)."""
    import pinocchio as pin

    model = system.pinocchio()[0]
    data = model.createData()
    frame = model.getFrameId("xray_source")
    J = pin.computeFrameJacobian(model, data, np.asarray(q, float), frame, pin.ReferenceFrame.LOCAL)
    omega = J[3:] @ w
    norm = float(np.linalg.norm(omega))
    if norm == 0.0:
        raise SweepError("the chosen joints do not turn the source")
    return omega / norm


def fan_angle(system, axis: np.ndarray) -> float:
    """Full fan angle (rad) of the beam in the plane of rotation about ``axis`` (source frame): the angle the
    detector subtends along its in-plane direction perpendicular to the axis's projection on the detector.
    Off-centre principal points count (the two half-angles are added)."""
    carm = system.carm
    K = carm.intrinsics()
    u0, v0 = K[0, 2], K[1, 2]
    sx, sy = carm.pixel_spacing
    f = carm.source_to_detector
    a = np.asarray(axis, float)[:2]
    # direction on the detector (x, y) perpendicular to the axis's projection; along x when the axis is the beam
    e = np.array([1.0, 0.0]) if np.linalg.norm(a) < 1e-12 else np.array([-a[1], a[0]]) / np.linalg.norm(a)
    corners = np.array([[(c - u0) * sx, (r - v0) * sy] for c in (-0.5, carm.detector_columns - 0.5)
                        for r in (-0.5, carm.detector_rows - 0.5)])
    t = corners @ e
    return float(math.atan(t.max() / f) - math.atan(t.min() / f))
